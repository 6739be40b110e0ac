#!/usr/bin/env bash
# Several shots in flight (issue 55 item 3, radiosity thesis ch. 5 "several emissions at once"):
# `radiosity SCENE --n N --residual R --in-flight K --shooter-choice C --reference` for K = 1, 2,
# 4, 8, 16 and both choices (table: Feda's central table, a new shooter as each shot lands;
# rounds: Thomin's top K per round). Per run: shots to the residual, the solution's span in shot
# durations (⌈shots / K⌉: K shots at a time), the machine's cycles summed over the shots, and
# the per-patch error against the f64 reference solver. Writes bench-out/radiosity_in_flight.csv
# and bench-out/radiosity_in_flight.md (the table of BENCHMARKS.md "Several shots in flight"
# with its header lines, also printed). SCENE (default cornell), N (64), RESIDUAL (0.01) and KS
# ("1 2 4 8 16") choose the runs; about 4 minutes on 2 cores with the defaults.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENE=${SCENE:-cornell}
N=${N:-64}
RESIDUAL=${RESIDUAL:-0.01}
KS=${KS:-"1 2 4 8 16"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=${CARGO_TARGET_DIR:-target}/release/host-sim
CSV=bench-out/radiosity_in_flight.csv
echo "scene,n,residual_target,in_flight,choice,shots,shot_times,residual,cycles,rms_relative_error,reference_shots,seconds" > "$CSV"
for k in $KS; do
  for c in table rounds; do
    [ "$k" = 1 ] && [ "$c" = rounds ] && continue  # one shot at a time: the choices coincide
    o=bench-out/in-flight-$SCENE-$N-k$k-$c
    extra=()
    [ "$k" != 1 ] && extra=(--in-flight "$k" --shooter-choice "$c")
    $B radiosity "$SCENE" --n "$N" --residual "$RESIDUAL" "${extra[@]}" --reference --quiet --stats "$o.json" 2> "$o.log"
    python3 - "$o.json" "$SCENE" "$N" "$RESIDUAL" "$k" "$c" >> "$CSV" <<'PY'
import json, math, sys
p, scene, n, target, k, c = sys.argv[1:]
j = json.load(open(p)); ref = j["reference"]
times = j["in_flight"]["shot_times"] if j.get("in_flight") else j["shots"]
print(",".join(map(str, [scene, n, target, k, c if int(k) > 1 else "one at a time", j["shots"], times, f"{j['residual']:.5f}",
      j["cycles"], f"{ref['rms_relative_error']:.4f}", ref["shots"], f"{j['wall_seconds']:.1f}"])))
PY
  done
done
. bench/lib.sh
{
  bench_header "SCENE=$SCENE N=$N RESIDUAL=$RESIDUAL KS=\"$KS\" bash bench/radiosity_in_flight.sh"
  echo
  python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
base = next(r for r in rows if r["in_flight"] == "1")
g = lambda v: f"{int(v):,}".replace(",", " ")
print("| shots in flight K | shooter choice | shots to the residual | span in shot durations | speed-up of the span | residual | grid cycles, all shots | rms relative error per patch vs f64 | host s |")
print("|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['in_flight']} | {r['choice']} | {r['shots']} | {r['shot_times']} | {int(base['shot_times']) / int(r['shot_times']):.1f}× | "
          f"{r['residual']} | {g(r['cycles'])} | {r['rms_relative_error']} | {r['seconds']} |")
PY
} | tee bench-out/radiosity_in_flight.md
