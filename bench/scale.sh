#!/usr/bin/env bash
# The simulator at scale. Renders each scene at each n as `host-sim render` ships (each scene in
# its default view, no f64 reference) and records wall time per phase, simulated cycles per
# phase, peak RSS; then fits the growth exponent of wall time in n. Writes bench-out/scale.csv
# and bench-out/scale.md (one markdown table per scene, with command, commit, machine, date).
#
#   SCENES="cornell bureau1" NS="128 256" THREADS="1 2" bash bench/scale.sh
#
# A run longer than LIMIT seconds (default 600) is stopped and recorded as a timeout. EXTRA adds
# render options to every run (e.g. EXTRA=--lit-visible-only for scenes whose columns need
# more lit runs than LIT_CAP). CSV (default bench-out/scale.csv) names the output.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENES=${SCENES:-"cornell bureau1 bureau2 classe cow70k-floor"}
NS=${NS:-"128 256 512 1024"}
THREADS=${THREADS:-"2"}
LIMIT=${LIMIT:-600}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
if [[ " $SCENES " == *" cow70k-floor "* && ! -f bench-out/cow70k-floor.obj ]]; then
  $B subdivide cow-floor --target 70000 --out bench-out/cow70k-floor.obj
fi
CSV=${CSV:-bench-out/scale.csv}
echo "scene,n,threads,facets,status,load_cycles,light_cycles,shade_cycles,beams_processed,messages,rays_skipped,load_s,light_s,shade_s,wall_s,peak_rss_mib" > "$CSV"
for scene in $SCENES; do
  src=$scene
  extra=()
  if [[ $scene == cow70k-floor ]]; then
    src=bench-out/cow70k-floor.obj
    # In front of the cow, like cow-floor's own light.
    extra=(--light 0.5,0.5,0.02)
  fi
  for n in $NS; do
    for t in $THREADS; do
      js=bench-out/scale-$scene-$n-t$t.json
      rm -f "$js"
      status=ok
      timeout "$LIMIT" $B render "$src" --n "$n" --threads "$t" --quiet "${extra[@]}" ${EXTRA:-} \
        --out "bench-out/scale-$scene-$n.png" --stats "$js" >/dev/null 2>bench-out/scale-err.txt || status=fail
      if [[ $status == fail ]]; then
        echo "$scene,$n,$t,,timeout_or_error,,,,,,,,,,," >> "$CSV"
        echo "  $scene n=$n threads=$t: $(tail -1 bench-out/scale-err.txt)" >&2
        continue
      fi
      python3 - "$js" "$scene" "$n" "$t" >> "$CSV" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); l = s["light"]
print(",".join(str(x) for x in [sys.argv[2], sys.argv[3], sys.argv[4], l["facets"], "ok", l["load_cycles"], l["cycles"],
      s["shade_cycles"], l["beams_processed"], l["messages"], l.get("rays_skipped", 0),
      f"{s['load_seconds']:.3f}", f"{s['light_seconds']:.3f}", f"{s['shade_seconds']:.3f}", f"{s['wall_seconds']:.3f}",
      f"{s['peak_rss_mib']:.0f}"]))
PY
      tail -1 "$CSV" >&2
    done
  done
done
. bench/lib.sh
{
bench_header "SCENES=\"$SCENES\" NS=\"$NS\" THREADS=\"$THREADS\"${EXTRA:+ EXTRA=\"$EXTRA\"} bash bench/scale.sh"
python3 - "$CSV" <<'PY'
import csv, math, sys
rows = [r for r in csv.DictReader(open(sys.argv[1]))]
def fit(pts):
    pts = [(math.log(n), math.log(w)) for n, w in pts if w > 0]
    if len(pts) < 2: return float("nan")
    mx = sum(p[0] for p in pts) / len(pts); my = sum(p[1] for p in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)
for scene in dict.fromkeys(r["scene"] for r in rows):
    rs = [r for r in rows if r["scene"] == scene]
    print(f"\n{scene}\n")
    print("| n | threads | facets | load cycles | light cycles | shade cycles | beams processed | messages | load s | light s | shade s | wall s | peak RSS MiB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rs:
        if r["status"] != "ok":
            print(f"| {r['n']} | {r['threads']} | — | not run: {r['status']} | | | | | | | | | |"); continue
        print(f"| {r['n']} | {r['threads']} | {r['facets']} | {r['load_cycles']} | {r['light_cycles']} | {r['shade_cycles']} | "
              f"{r['beams_processed']} | {r['messages']} | {r['load_s']} | {r['light_s']} | {r['shade_s']} | {r['wall_s']} | {r['peak_rss_mib']} |")
    for t in dict.fromkeys(r["threads"] for r in rs):
        ok = [r for r in rs if r["threads"] == t and r["status"] == "ok"]
        print(f"\nwall-time exponent in n ({t} threads, n = {', '.join(r['n'] for r in ok)}): "
              f"{fit([(int(r['n']), float(r['wall_s'])) for r in ok]):.2f}")
PY
} | tee "${CSV%.csv}.md"
