#!/usr/bin/env bash
# Mirror reflections on the grid: cornell-mirror at each n and tree depth against
# the f64 reference with the same reflections, then the discrete-space defects of thesis §5.5 at
# n = 64 (face-flip normals, self-collisions on thick surfaces, 26-connected rays through naive
# walls), and the three intersection rules of §5.3 (--hit centre|edge|exact) at each n.
# Writes bench-out/reflections.csv, prints a markdown table, and with PICTURES=1 writes the
# small PNGs of docs/ (needs python3 with Pillow). NS (default "64 128") and DEPTHS choose runs.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"64 128"}
DEPTHS=${DEPTHS:-"1 2 4"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/reflections.csv
echo "scene,n,variant,hit,depth,roots,rays,hits,exits,waits,max_level,cycles,ray_messages,answer_messages,peak_fifo,peak_wait,psnr_db,psnr_without_db,mirror_psnr_db,mirror_psnr_without_db,mirror_pixels,shadow_disagreement_pct,reflect_wall_s" > "$CSV"
run() { # name n variant depth extra-args...
  local scene=$1 n=$2 variant=$3 depth=$4; shift 4
  local o=bench-out/refl-$scene-$n-$variant-d$depth
  $B render "$scene" --n "$n" --reflections "$depth" --reference --quiet --out "$o.png" --stats "$o.json" "$@" 2> "$o.log"
  python3 - "$o.json" "$scene" "$n" "$variant" "$depth" >> "$CSV" <<'PY'
import json, sys
p, scene, n, variant, depth = sys.argv[1:]
s = json.load(open(p)); r = s["reflections"]; ref = s["reference"]
f = lambda v: f"{v:.2f}"
print(",".join(map(str, [scene, n, variant, r["hit"], depth, r["roots"], r["rays"], r["hits"], r["exits"], r["waits"], r["max_level"],
      r["cycles"], r["ray_messages"], r["answer_messages"], r["peak_fifo"], r["peak_wait"], f(r["psnr_db"]), f(r["psnr_without_db"]),
      f(r["mirror_psnr_db"]), f(r["mirror_psnr_without_db"]), r["mirror_pixels"], f(ref["shadow_disagreement_pct"]),
      f(s["shade_seconds"])])))
PY
}
for n in $NS; do
  for d in $DEPTHS; do run cornell-mirror "$n" facet "$d"; done
  run cornell-mirror "$n" hit-edge 2 --hit edge
  run cornell-mirror "$n" hit-exact 2 --hit exact
  run cornell-mirror "$n" hit-edge-26 2 --hit edge --ray-connectivity 26
  run cornell-mirror "$n" hit-exact-26 2 --hit exact --ray-connectivity 26
done
run cornell-mirror 64 face-flip 2 --reflect-normal face
run cornell-mirror 64 standard-sigma 2 --sigma standard
run cornell-mirror 64 standard-sigma-self-hits 2 --sigma standard --reflect-self-hits
run cornell-mirror 64 self-hits 2 --reflect-self-hits
run cornell-mirror 64 rays-26 2 --ray-connectivity 26
run cornell-mirror 64 rays-18 2 --ray-connectivity 18
. bench/lib.sh
bench_header "PICTURES=${PICTURES:-0} NS=\"$NS\" DEPTHS=\"$DEPTHS\" bash bench/reflections.sh"
echo
python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("| n | variant | hit | depth | trees | rays | hits / exits | waits | deepest level | cycles | ray + answer messages | peak FIFO / wait table | PSNR dB (without) | mirror PSNR dB (without) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['n']} | {r['variant']} | {r['hit']} | {r['depth']} | {r['roots']} | {r['rays']} | {r['hits']} / {r['exits']} | {r['waits']} | {r['max_level']} | "
          f"{r['cycles']} | {r['ray_messages']} + {r['answer_messages']} | {r['peak_fifo']} / {r['peak_wait']} | "
          f"{r['psnr_db']} ({r['psnr_without_db']}) | {r['mirror_psnr_db']} ({r['mirror_psnr_without_db']}) |")
PY
if [ "${PICTURES:-0}" = 1 ]; then
  python3 - <<'PY'
from PIL import Image, ImageDraw
def im(p): return Image.open(p).convert("RGB")
def strip(paths, out, scale):
    ims = [im(p) for p in paths]
    w, h = ims[0].size
    s = Image.new("RGB", (len(ims) * (w * scale + 4) - 4, h * scale), (255, 255, 255))
    for i, x in enumerate(ims):
        s.paste(x.resize((w * scale, h * scale), Image.NEAREST), (i * (w * scale + 4), 0))
    s.save(out, optimize=True)
o = "bench-out/refl-cornell-mirror"
for sfx in ("png", "reference.png", "diff.png"):
    im(f"{o}-128-facet-d2.{sfx}").save(f"docs/reflect-cornell-mirror-128.{sfx}", optimize=True)
# Each defect: grid (facet normals, thin surface, 6-connected rays) | defect variant | reference.
for name, v in [("face-flip", "face-flip"), ("self-hits", "standard-sigma-self-hits"), ("rays-26", "rays-26")]:
    base = f"{o}-64-standard-sigma-d2.png" if name == "self-hits" else f"{o}-64-facet-d2.png"
    strip([base, f"{o}-64-{v}-d2.png", f"{o}-64-facet-d2.reference.png"], f"docs/reflect-defect-{name}.png", 2)
PY
  ls -l docs/reflect-*
fi
