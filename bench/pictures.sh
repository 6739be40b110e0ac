#!/usr/bin/env bash
# Regenerates the README's pictures in docs/ with the current defaults:
#   docs/cornell{,.reference,.diff}.png       render cornell --n 128 --reference (its camera)
#   docs/teapot-floor{,.reference,.diff}.png  render teapot-floor --n 256 --reference
#   docs/cornell-camera-256.png  render cornell --n 256 --reference: machine | reference | difference
#   docs/grazing.png  the tall block's front face, lit by the Cornell light at a degree or two
#                     (n = 256, fitted view, ×2), before and after: the thesis's rule and setup |
#                     plane rule (the former default) | exact occluders (the default) | f64 reference
# Needs python3 with Pillow (`pip install pillow`) for the grazing montage.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-sim
B=./target/release/host-sim
$B render cornell --n 128 --reference --quiet --out docs/cornell.png
$B render teapot-floor --n 256 --reference --quiet --out docs/teapot-floor.png
T=$(mktemp -d)
$B render cornell --n 256 --reference --quiet --out "$T/camera.png"
python3 - "$T" <<'PY'
import sys
from PIL import Image
t = sys.argv[1]
panels = [Image.open(f"{t}/camera{p}.png").convert("RGB") for p in ("", ".reference", ".diff")]
w, h = panels[0].size
out = Image.new("RGB", (3 * w, h))
for i, p in enumerate(panels):
    out.paste(p, (i * w, 0))
out.save("docs/cornell-camera-256.png")
PY
$B render cornell --n 256 --view fitted --quiet --out "$T/thesis.png" \
  --lit-rule thesis --rays-from voxel --sigma naive --contour projected --frac-bits 0 --policy wavefront
$B render cornell --n 256 --view fitted --quiet --lit-rule plane --rays-from voxel --out "$T/plane.png"
$B render cornell --n 256 --view fitted --reference --quiet --out "$T/exact.png"
python3 - "$T" <<'PY'
import sys
from PIL import Image
t = sys.argv[1]
box = (50, 95, 140, 235)  # the tall block's front face at n = 256
panels = [Image.open(f"{t}/{p}.png").convert("RGB").crop(box) for p in ("thesis", "plane", "exact", "exact.reference")]
w, h = panels[0].size
gap = 5
out = Image.new("RGB", (4 * w + 3 * gap, h), "white")
for i, p in enumerate(panels):
    out.paste(p, (i * (w + gap), 0))
out.resize((out.width * 2, out.height * 2), Image.NEAREST).save("docs/grazing.png")
PY
rm -r "$T"
echo "wrote docs/cornell*.png docs/teapot-floor*.png docs/cornell-camera-256.png docs/grazing.png"
