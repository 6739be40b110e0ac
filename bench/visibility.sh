#!/usr/bin/env bash
# The lit-ray ratio (issue 54 item 5(a); thesis §5.5.5): `render SCENE --visibility V --reference`
# for V = target (the default: a pixel is lit iff its target ray arrives), ratio (the share of its
# target voxel's rays that arrive weighs the light) and majority (lit iff more than half arrive),
# on Cornell through its camera, teapot-floor and bureau1, at n = 128 and 256, f = 0 and 2. Each
# image is compared with both f64 references: the point reference (the pixel's centre decides,
# what `target` approximates) and the footprint reference (8 × 8 points of the pixel on its
# surface, what `ratio` and `majority` approximate; `render --visibility ratio --reference`
# writes it). Writes bench-out/visibility.csv and bench-out/visibility.md (the table of
# BENCHMARKS.md "Pixels lit by a share of their rays" with its header lines, also printed); with
# PICTURES=1 also docs/visibility-teapot-256.png (teapot-floor, n = 256, f = 2: target, ratio,
# footprint reference; the spout's shadow ×2). PSNRs over every pixel, as `render` computes them, with Pillow and
# NumPy through bench/venv.sh. SCENES, NS and FS choose the runs (about 10 minutes on 2 cores
# with the defaults); TAG=T names the outputs bench-out/visibility-T.{csv,md} instead.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENES=${SCENES:-"cornell teapot-floor bureau1"}
NS=${NS:-"128 256"}
FS=${FS:-"0 2"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=${CARGO_TARGET_DIR:-target}/release/host-sim
. bench/venv.sh
PY=$(bench_python pillow numpy)  # "import pillow" fails, so pip checks it each time (quick)
OUT=bench-out/visibility${TAG:+-$TAG}
CSV=$OUT.csv
echo "scene,n,f,visibility,psnr_point_db,psnr_footprint_db,point_vs_footprint_db,light_cycles,beams,messages,light_seconds" > "$CSV"
for scene in $SCENES; do
  for n in $NS; do
    for f in $FS; do
      o=bench-out/vis-$scene-$n-f$f
      for v in target ratio majority; do
        $B render "$scene" --n "$n" --frac-bits "$f" --visibility "$v" --reference --quiet \
          --out "$o-$v.png" --stats "$o-$v.json" 2> "$o-$v.log"
      done
      "$PY" - "$o" "$scene" "$n" "$f" >> "$CSV" <<'PY'
import json, sys
import numpy as np
from PIL import Image
o, scene, n, f = sys.argv[1:]
img = lambda p: np.asarray(Image.open(p).convert("RGB"), dtype=np.float64)
def psnr(a, b):
    mse = ((a - b) ** 2).mean()
    return float("inf") if mse == 0 else 10 * np.log10(255 ** 2 / mse)
point, foot = img(f"{o}-target.reference.png"), img(f"{o}-ratio.reference.png")
for v in ["target", "ratio", "majority"]:
    j = json.load(open(f"{o}-{v}.json")); t = j["light"]; m = img(f"{o}-{v}.png")
    own = foot if v == "ratio" else img(f"{o}-{v}.reference.png")
    # The render's own PSNR is against the reference computed its way; check it is ours.
    assert abs(psnr(m, own) - j["reference"]["psnr_db"]) < 0.01, (v, psnr(m, own), j["reference"]["psnr_db"])
    print(",".join(map(str, [scene, n, f, v, f"{psnr(m, point):.2f}", f"{psnr(m, foot):.2f}", f"{psnr(point, foot):.2f}",
          t["cycles"], t["beams_processed"], t["messages"], f"{j['light_seconds']:.2f}"])))
PY
    done
  done
done
. bench/lib.sh
{
  bench_header "SCENES=\"$SCENES\" NS=\"$NS\" FS=\"$FS\"${TAG:+ TAG=$TAG} bash bench/visibility.sh"
  echo
  python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
g = lambda v: f"{int(v):,}".replace(",", " ")
print("| scene | n | f | visibility | PSNR dB vs point reference | PSNR dB vs footprint reference | point vs footprint reference dB | light cycles | beams | messages | light s |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['scene']} | {r['n']} | {r['f']} | {r['visibility']} | {r['psnr_point_db']} | {r['psnr_footprint_db']} | "
          f"{r['point_vs_footprint_db']} | {g(r['light_cycles'])} | {g(r['beams'])} | {g(r['messages'])} | {r['light_seconds']} |")
PY
} | tee "$OUT.md"
if [ "${PICTURES:-0}" = 1 ]; then
  "$PY" - <<'PY'
from PIL import Image
o = "bench-out/vis-teapot-floor-256-f2"
paths = [f"{o}-target.png", f"{o}-ratio.png", f"{o}-ratio.reference.png"]
box = (12, 120, 140, 248)  # the spout's shadow on the floor (image rows top down), shown ×2
k = 2
ims = [Image.open(p).convert("RGB").crop(box) for p in paths]
ims = [i.resize((k * i.width, k * i.height), Image.NEAREST) for i in ims]
cw, ch = ims[0].size
out = Image.new("RGB", (3 * cw + 8, ch), (255, 255, 255))
for x, i in enumerate(ims):
    out.paste(i, (x * (cw + 4), 0))
out.save("docs/visibility-teapot-256.png", optimize=True)
PY
  ls -l docs/visibility-teapot-256.png
fi
