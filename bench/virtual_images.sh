#!/usr/bin/env bash
# Thesis §5.5.4: a point source's rays reflected by a voxelized flat mirror (tilted TILT degrees,
# a staircase), for each grid size, hit rule (§5.3) and normal (§5.2): the spread of the virtual
# images around S′ and the dark zone on a screen (host-sim virtual-images). Writes
# bench-out/virtual_images.csv and prints a markdown table; PICTURES=1 also writes
# docs/virtual-images-N-facet-centre.png for each N, and -facet-exact / -face-centre for the last N.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"32 128"}
HITS=${HITS:-"centre edge exact"}
TILT=${TILT:-20}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/virtual_images.csv
rm -f "$CSV"
for n in $NS; do
  for normal in facet face; do
    for hit in $HITS; do
      o=bench-out/vi-$n-$normal-$hit
      $B virtual-images --n "$n" --hit "$hit" --reflect-normal "$normal" --tilt "$TILT" --out "$o.png" --csv "$o.csv" > "$o.log"
      if [ -s "$CSV" ]; then tail -n 1 "$o.csv" >> "$CSV"; else cat "$o.csv" > "$CSV"; fi
    done
  done
done
. bench/lib.sh
bench_header "PICTURES=${PICTURES:-0} NS=\"$NS\" HITS=\"$HITS\" TILT=$TILT bash bench/virtual_images.sh"
echo
python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("| n | normal | hit | rays reflected | closest approach to S′, voxels: mean / rms / max | within 1 voxel | footprint cells | dark % (same rays reflected exactly) |")
print("|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['n']} | {r['normal'].lower()} | {r['hit'].lower()} | {r['reflected']} | {float(r['spread_mean_voxels']):.2f} / {float(r['spread_rms_voxels']):.2f} / {float(r['spread_max_voxels']):.2f} | "
          f"{100 * float(r['within_one_voxel']):.1f} % | {r['footprint_cells']} | {float(r['dark_pct']):.2f} ({float(r['dark_continuous_pct']):.2f}) |")
PY
if [ "${PICTURES:-0}" = 1 ]; then
  # The dark zone at both sizes; the exact hit and the face flip at the finer one.
  for n in $NS; do cp "bench-out/vi-$n-facet-centre.png" "docs/virtual-images-$n-facet-centre.png"; done
  last=${NS##* }
  for v in facet-exact face-centre; do cp "bench-out/vi-$last-$v.png" "docs/virtual-images-$last-$v.png"; done
  ls -l docs/virtual-images-*.png
fi
