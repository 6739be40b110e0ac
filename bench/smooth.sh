#!/usr/bin/env bash
# Smooth shading (issue 54 item 4): `render --normals facet|gouraud|phong --reference` on meshes
# without vertex normals in the file (teapot-floor: averaged) and with them (suzanne: its `vn`),
# at two resolutions; each image against the f64 reference shaded the same way. Writes
# bench-out/smooth.csv and prints the markdown table of BENCHMARKS.md ("Smooth shading") with its
# header lines; with PICTURES=1 also docs/smooth-vs-flat.png (teapot-floor at n = 128, ×2: facet |
# phong | gouraud | phong reference; Pillow through bench/venv.sh). NS (default "64 128") and
# SCENES (default "teapot-floor suzanne") choose the runs. ~1 minute on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"64 128"}
SCENES=${SCENES:-"teapot-floor suzanne"}
MODES="facet gouraud phong"
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/smooth.csv
echo "scene,n,normals,normals_from,facets,polygons_cut,covered,psnr_db,shadow_disagreement_pct,shading_max_err_levels,bytes_per_cell,bytes_per_packet_extra,bytes_per_cell_extra" > "$CSV"
for scene in $SCENES; do
  for n in $NS; do
    for mode in $MODES; do
      o=bench-out/smooth-$scene-$n-$mode
      $B render "$scene" --n "$n" --normals "$mode" --reference --quiet --out "$o.png" --stats "$o.json" 2> "$o.log"
      python3 - "$o.json" "$scene" "$n" >> "$CSV" <<'PY'
import json, sys
p, scene, n = sys.argv[1:]
s = json.load(open(p)); ref = s["reference"]; sm = s.get("smooth")
print(",".join(map(str, [scene, n, s["normals"], sm["normals_from"] if sm else "-", s["light"]["facets"],
      sm["polygons_cut"] if sm else 0, s["covered_pixels"], f"{ref['psnr_db']:.2f}", f"{ref['shadow_disagreement_pct']:.2f}",
      s["shading_max_err_levels"], s["bytes_per_cell"], sm["bytes_per_packet"] if sm else 0, sm["bytes_per_cell"] if sm else 0])))
PY
    done
  done
done
. bench/lib.sh
bench_header "NS=\"$NS\" SCENES=\"$SCENES\" bash bench/smooth.sh"
echo
python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("| scene | n | normals | vertex normals | facets (polygons cut) | PSNR dB vs the reference shaded the same way | shadow disagreement % | cell vs f64, max levels | bytes/cell | + bytes/packet | + bytes/cell |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['scene']} | {r['n']} | {r['normals']} | {r['normals_from']} | {r['facets']} ({r['polygons_cut']}) | {r['psnr_db']} | "
          f"{r['shadow_disagreement_pct']} | {r['shading_max_err_levels']} | {r['bytes_per_cell']} | {r['bytes_per_packet_extra']} | {r['bytes_per_cell_extra']} |")
PY
if [ "${PICTURES:-0}" = 1 ]; then
  . bench/venv.sh
  PY=$(bench_python pillow)  # "import pillow" fails, so pip checks it each time (quick)
  "$PY" - <<'PY'
from PIL import Image
o = "bench-out/smooth-teapot-floor-128"
paths = [f"{o}-facet.png", f"{o}-phong.png", f"{o}-gouraud.png", f"{o}-phong.reference.png"]
ims = [Image.open(p).convert("RGB") for p in paths]
box = (22, 34, 112, 84)  # the teapot at n = 128 (image rows top down), shown ×2
ims = [i.crop(box).resize((2 * (box[2] - box[0]), 2 * (box[3] - box[1])), Image.NEAREST) for i in ims]
cw, ch = ims[0].size
out = Image.new("RGB", (len(ims) * (cw + 4) - 4, ch), (255, 255, 255))
for k, i in enumerate(ims):
    out.paste(i, (k * (cw + 4), 0))
out.save("docs/smooth-vs-flat.png", optimize=True)
PY
  ls -l docs/smooth-vs-flat.png
fi
