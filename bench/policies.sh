#!/usr/bin/env bash
# Which policy, sibling wait, skips and FIFO size (thesis §4.4.1; the skips are rc2's): `render SCENE --n N`
# as shipped (the first row of each scene and n), then one option changed at a time. Policies,
# the wait and the skips change which beams are processed when, never which voxels are lit, so
# the table compares cycles, the lower bound LB, beams and messages (exact counts) and the lit
# pixels (which must not move). Host seconds of the light phase are one run on whatever else the
# machine is doing.
#   SCENES default: "cornell bureau1 teapot-floor" (cornell through its camera, the others fitted)
#   NS     default: "128 256"
# Writes bench-out/policies.csv and bench-out/policies.md (BENCHMARKS.md's table, with command,
# commit, machine and date). ~5 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENES=${SCENES:-"cornell bureau1 teapot-floor"}
NS=${NS:-"128 256"}
mkdir -p bench-out/policies
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/policies.csv
echo "scene,n,variant,cycles,lower_bound,t_over_lb,beams,messages,lit_pixels,light_s" > "$CSV"
VARIANTS=("the default (radial + merge, no wait, every skip, 32 blocks)|"
  "wavefront policy|--policy wavefront"
  "the thesis's policy (FIFO head)|--policy thesis"
  "sibling wait 4|--hold 4"
  "no hidden-voxel skip|--skip-hidden false"
  "8-block summary|--frustum-blocks 8"
  "no receding / dead-direction skip|--skip-receding false --skip-dead-directions false"
  "FIFO of 8 (FA = 8)|--fa 8"
  "FIFO of 32 (FA = 32)|--fa 32")
for n in $NS; do
  for scene in $SCENES; do
    for v in "${VARIANTS[@]}"; do
      name=${v%%|*}; read -r -a opts <<< "${v#*|}"
      o=bench-out/policies/$scene-$n-$(echo "${v#*|}" | tr -c 'a-z0-9' '_')
      $B render "$scene" --n "$n" --quiet "${opts[@]}" --out "$o.png" --stats "$o.json" 2> "$o.log"
      python3 - "$o.json" "$scene" "$n" "$name" >> "$CSV" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); l = s["light"]
print(f"{sys.argv[2]},{sys.argv[3]},\"{sys.argv[4]}\",{l['cycles']},{l['lower_bound']},{l['t_over_lb']:.2f},"
      f"{l['beams_processed']},{l['messages']},{s['lit_pixels']},{s['light_seconds']:.2f}")
PY
      tail -1 "$CSV"
    done
  done
done
. bench/lib.sh
{
  bench_header "SCENES=\"$SCENES\" NS=\"$NS\" bash bench/policies.sh"
  echo
  python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
first = {}
sp = lambda x: f"{int(x):,}".replace(",", " ")
print("| scene | n | variant | cycles | LB | T/LB | beams | messages | lit pixels | light s |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    k = (r["scene"], r["n"])
    base = first.setdefault(k, r)
    rel = "" if r is base else f" ({int(r['cycles']) / int(base['cycles']):.2f}×)"
    lit = r["lit_pixels"] if r["lit_pixels"] == base["lit_pixels"] else f"**{r['lit_pixels']}** (moved)"
    name = f"**{r['variant']}**" if r is base else r["variant"]
    print(f"| {r['scene']} | {r['n']} | {name} | {sp(r['cycles'])}{rel} | {sp(r['lower_bound'])} | {r['t_over_lb']} | "
          f"{sp(r['beams'])} | {sp(r['messages'])} | {lit} | {r['light_s']} |")
PY
} | tee bench-out/policies.md
