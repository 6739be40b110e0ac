#!/usr/bin/env bash
# Area lights and penumbrae (issue 54 item 5(b)): `render cornell --area-light S --reference`, the
# Cornell box through its camera with its ceiling lamp sampled by S × S point sources, each image
# against the f64 reference that samples the same points with the same weights. Writes
# bench-out/area_light.csv and bench-out/area_light.md (the table of BENCHMARKS.md "Area lights and
# penumbrae" with its header lines, also printed); with PICTURES=1 also docs/penumbra.png (n = 128:
# S = 1 beside S = 4, machine above reference, cropped to the blocks' shadows; Pillow through
# bench/venv.sh). NS (default "128 256") and SS (default "1 2 3 4 5": S = 5 is 25 sources, the
# most under the machine's 32) choose the runs. The lighting time grows with S² (one diffusion per
# sample): about 20 minutes on 2 cores with the defaults.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"128 256"}
SS=${SS:-"1 2 3 4 5"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=${CARGO_TARGET_DIR:-target}/release/host-sim
CSV=bench-out/area_light.csv
echo "scene,n,S,sources,psnr_db,shadow_disagreement_pct,coverage_disagreement_pct,lit_pixels,light_cycles,beams,light_seconds,reference_seconds" > "$CSV"
for n in $NS; do
  for s in $SS; do
    o=bench-out/area-cornell-$n-s$s
    $B render cornell --n "$n" --area-light "$s" --reference --quiet --out "$o.png" --stats "$o.json" 2> "$o.log"
    python3 - "$o.json" "$n" "$s" >> "$CSV" <<'PY'
import json, sys
p, n, s = sys.argv[1:]
j = json.load(open(p)); ref = j["reference"]; t = j["light"]
print(",".join(map(str, ["cornell", n, s, len(j["light"]["sources"]), f"{ref['psnr_db']:.2f}", f"{ref['shadow_disagreement_pct']:.2f}",
      f"{ref['coverage_disagreement_pct']:.2f}", j["lit_pixels"], t["cycles"], t["beams_processed"], f"{j['light_seconds']:.1f}",
      f"{j['reference_seconds']:.1f}"])))
PY
  done
done
. bench/lib.sh
{
  bench_header "NS=\"$NS\" SS=\"$SS\" bash bench/area_light.sh"
  echo
  python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
g = lambda v: f"{int(v):,}".replace(",", " ")
print("| n | S | point sources | PSNR dB vs the reference sampled the same way | shadow disagreement % per (pixel, source) | lit pixels | light cycles | beams | light s | reference s |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['n']} | {r['S']} | {r['sources']} | {r['psnr_db']} | {r['shadow_disagreement_pct']} | {g(r['lit_pixels'])} | "
          f"{g(r['light_cycles'])} | {g(r['beams'])} | {r['light_seconds']} | {r['reference_seconds']} |")
PY
} | tee bench-out/area_light.md
if [ "${PICTURES:-0}" = 1 ]; then
  . bench/venv.sh
  PY=$(bench_python pillow)  # "import pillow" fails, so pip checks it each time (quick)
  "$PY" - <<'PY'
from PIL import Image
o = "bench-out/area-cornell-128"
rows = [[f"{o}-s1.png", f"{o}-s4.png"], [f"{o}-s1.reference.png", f"{o}-s4.reference.png"]]
box = (16, 56, 116, 126)  # the floor under the blocks at n = 128 (image rows top down), shown ×3
k = 3
ims = [[Image.open(p).convert("RGB").crop(box) for p in r] for r in rows]
ims = [[i.resize((k * i.width, k * i.height), Image.NEAREST) for i in r] for r in ims]
cw, ch = ims[0][0].size
out = Image.new("RGB", (2 * cw + 4, 2 * ch + 4), (255, 255, 255))
for y, r in enumerate(ims):
    for x, i in enumerate(r):
        out.paste(i, (x * (cw + 4), y * (ch + 4)))
out.save("docs/penumbra.png", optimize=True)
PY
  ls -l docs/penumbra.png
fi
