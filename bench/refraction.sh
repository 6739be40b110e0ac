#!/usr/bin/env bash
# Refraction on the grid (thesis §1.1, §1.2.5; the defects of §5.5.2): cornell-glass (the Cornell
# box with its short block and a sphere of glass, Ni 1.5, Kt 0.9) at each n and tree depth
# against the f64 reference with the same reflected and refracted branches; then, at the first
# n, the three hit rules of §5.3 and the rays' connectivity and the surfaces' thickness, which
# decide how many rays inside a solid leak out through its voxelized surface; and the sphere
# alone as glass (a closed solid: every ray inside it that meets another material or leaves
# the grid went through its surface, §5.5.2) at each n, standard and naive surfaces, 6- and
# 26-connected rays.
# Writes bench-out/refraction.csv and prints a markdown table; PICTURES=1 also writes
# docs/refract-cornell-glass-128.png (grid | reference | difference; needs Pillow).
# NS (default "64 128") and DEPTHS (default "2 4 8") choose the runs.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"64 128"}
DEPTHS=${DEPTHS:-"2 4 8"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/refraction.csv
echo "scene,n,variant,hit,depth,roots,rays,refracted,total_internal,leaks,hits,exits,waits,max_level,cycles,ray_messages,answer_messages,peak_wait,psnr_db,psnr_without_db,glass_psnr_db,glass_psnr_without_db,glass_pixels,reflect_wall_s" > "$CSV"
run() { # scene n variant depth extra-args...
  local scene=$1 n=$2 variant=$3 depth=$4; shift 4
  local o=bench-out/refr-$(basename "$scene" .obj)-$n-$variant-d$depth
  $B render "$scene" --n "$n" --reflections "$depth" --reference --quiet --out "$o.png" --stats "$o.json" "$@" 2> "$o.log" \
    || { cat "$o.log" >&2; exit 1; }
  python3 - "$o.json" "$scene" "$n" "$variant" "$depth" >> "$CSV" <<'PY'
import json, sys
p, scene, n, variant, depth = sys.argv[1:]
s = json.load(open(p)); r = s["reflections"]
f = lambda v: f"{v:.2f}"
print(",".join(map(str, [scene, n, variant, r["hit"], depth, r["roots"], r["rays"], r["refracted"], r["total_internal"],
      r["leaks"], r["hits"], r["exits"], r["waits"], r["max_level"], r["cycles"], r["ray_messages"], r["answer_messages"],
      r["peak_wait"], f(r["psnr_db"]), f(r["psnr_without_db"]), f(r["glass_psnr_db"]), f(r["glass_psnr_without_db"]),
      r["glass_pixels"], f(s["shade_seconds"])])))
PY
}
first=${NS%% *}
for n in $NS; do
  for d in $DEPTHS; do run cornell-glass "$n" facet "$d"; done
done
run cornell-glass "$first" hit-edge 4 --hit edge
run cornell-glass "$first" hit-exact 4 --hit exact
run cornell-glass "$first" rays-18 4 --ray-connectivity 18
run cornell-glass "$first" rays-26 4 --ray-connectivity 26
run cornell-glass "$first" naive-sigma 4 --sigma naive
run cornell-glass "$first" naive-sigma-rays-26 4 --sigma naive --ray-connectivity 26
run cornell-glass "$first" self-hits 4 --reflect-self-hits
# The leaks of one closed solid: the same box with the short block opaque (its base is open on
# the floor, so rays inside it that meet the floor count as leaks there), the sphere alone glass.
sed '/^o short_block/,/^o tall_block/s/^usemtl glass/usemtl white/' host-sim/scenes/cornell-glass.obj > bench-out/sphere-glass.obj
cp host-sim/scenes/cornell-glass.mtl bench-out/cornell-glass.mtl
for n in $NS; do
  for sigma in standard naive; do
    for conn in 6 26; do
      run bench-out/sphere-glass.obj "$n" "sphere-$sigma-rays-$conn" 4 --sigma "$sigma" --ray-connectivity "$conn"
    done
  done
done
. bench/lib.sh
bench_header "PICTURES=${PICTURES:-0} NS=\"$NS\" DEPTHS=\"$DEPTHS\" bash bench/refraction.sh"
echo
python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("| scene | n | variant | hit | depth | trees | rays | refracted (total internal) | leaks | hits / exits | waits | deepest level | cycles | ray + answer messages | peak wait table | PSNR dB (without) | glass PSNR dB (without) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['scene'].split('/')[-1].removesuffix('.obj')} | {r['n']} | {r['variant']} | {r['hit']} | {r['depth']} | {r['roots']} | {r['rays']} | {r['refracted']} ({r['total_internal']}) | "
          f"{r['leaks']} | {r['hits']} / {r['exits']} | {r['waits']} | {r['max_level']} | {r['cycles']} | "
          f"{r['ray_messages']} + {r['answer_messages']} | {r['peak_wait']} | {r['psnr_db']} ({r['psnr_without_db']}) | "
          f"{r['glass_psnr_db']} ({r['glass_psnr_without_db']}) |")
PY
if [ "${PICTURES:-0}" = 1 ]; then
  python3 - "$(echo "$NS" | awk '{print $NF}')" <<'PY'
import sys
from PIL import Image
n = sys.argv[1]
o = f"bench-out/refr-cornell-glass-{n}-facet-d4"
ims = [Image.open(f"{o}.{s}").convert("RGB") for s in ("png", "reference.png", "diff.png")]
w, h = ims[0].size
strip = Image.new("RGB", (3 * w + 8, h), (255, 255, 255))
for i, im in enumerate(ims):
    strip.paste(im, (i * (w + 4), 0))
strip.save(f"docs/refract-cornell-glass-{n}.png", optimize=True)
PY
  ls -l docs/refract-*
fi
