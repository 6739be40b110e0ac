#!/usr/bin/env bash
# Meshes under lights of their own, as a new user would try them: each mesh of MESHES (OBJ files
# of ../shared/scenes or any path) under each light of LIGHTS, rendered at each n of NS with
# `render MESH --light L --reference`, by the defaults (beam diffusion, exact occluders), by the
# plane rule and by classic shadow rays. Writes bench-out/unseen.csv (shadow disagreement, PSNR, light cycles per run) and
# prints the mean and the worst run per method and n.
#   MESHES  default: suzanne fandisk cow teapot (looked up in ../shared/scenes/NAME.obj)
#   LIGHTS  default: 0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9 (grid-normalised)
#   NS      default: 256
#   METHODS default: "exact plane classic" (exact: the defaults; plane: --lit-rule plane
#           --rays-from voxel, the former default; classic: --lighting classic, under exact
#           occluders; classic-plane: --lighting classic --lit-rule plane; refined:
#           --lighting refined, cycles of both phases)
#   ROTATE  default: none. Rotations of each mesh to render instead of the mesh as stored, each
#           a sequence of axis and angle in radians applied in order (x0.6y0.9: 0.6 about x,
#           then 0.9 about y); "none" is the mesh as stored. The rotated OBJ is written to
#           bench-out/unseen/MESH-ROTATION.obj (vertices only: normals and texture coordinates
#           dropped).
#   APPEND=1 adds to the CSV instead of starting it anew.
# Also writes bench-out/unseen.md: BENCHMARKS.md's table (per n and method: each mesh's mean /
# worst shadow disagreement over its lights and rotations, all runs' mean / worst, the worst
# PSNR, the mean light cycles), methods in METHODS order, with command, commit, machine, date.
set -euo pipefail
cd "$(dirname "$0")/.."
MESHES=${MESHES:-"suzanne fandisk cow teapot"}
LIGHTS=${LIGHTS:-"0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9"}
NS=${NS:-256}
METHODS=${METHODS:-"exact plane classic"}
ROTATE=${ROTATE:-none}
mkdir -p bench-out/unseen
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/unseen.csv
[[ ${APPEND:-0} == 1 && -f $CSV ]] || echo "mesh,light,n,method,shadow_disagreement_pct,psnr_db,cycles" > "$CSV"
# rotated MESH_OBJ ROTATION: prints the path of the mesh under ROTATION (itself for "none").
rotated() {
  [[ $2 == none ]] && { echo "$1"; return; }
  local out=bench-out/unseen/$(basename "$1" .obj)-$2.obj
  python3 - "$1" "$2" "$out" <<'PY'
import math, re, sys
src, spec, out = sys.argv[1:]
ops = [(a, float(x)) for a, x in re.findall(r"([xyz])(-?[0-9.]+)", spec)]
def rot(v, ax, t):
    c, s = math.cos(t), math.sin(t); x, y, z = v
    return {"x": (x, c*y - s*z, s*y + c*z), "y": (c*x + s*z, y, -s*x + c*z), "z": (c*x - s*y, s*x + c*y, z)}[ax]
lines = []
for l in open(src):
    if l.startswith("v "):
        v = tuple(map(float, l.split()[1:4]))
        for ax, t in ops:
            v = rot(v, ax, t)
        lines.append("v %.6f %.6f %.6f" % v)
    elif l.startswith("f "):
        lines.append("f " + " ".join(w.split("/")[0] for w in l.split()[1:]))
    elif not l.startswith(("vn ", "vt ")):
        lines.append(l.rstrip("\n"))
open(out, "w").write("\n".join(lines) + "\n")
PY
  echo "$out"
}
for n in $NS; do
  for base in $MESHES; do
   base_obj=$base; [[ -f $base_obj ]] || base_obj=../shared/scenes/$base.obj
   for rotation in $ROTATE; do
    obj=$(rotated "$base_obj" "$rotation")
    mesh=$(basename "$base" .obj); [[ $rotation == none ]] || mesh=$mesh-$rotation
    for light in $LIGHTS; do
      for m in $METHODS; do
        case $m in
          plane) opts=(--lit-rule plane --rays-from voxel) ;;
          classic) opts=(--lighting classic) ;;
          classic-plane) opts=(--lighting classic --lit-rule plane) ;;
          exact) opts=() ;;
          refined) opts=(--lighting refined) ;;
          *) echo "unknown method $m" >&2; exit 2 ;;
        esac
        o=bench-out/unseen/$mesh-$light-$n-$m
        $B render "$obj" --n "$n" --light "$light" --reference --quiet "${opts[@]}" --out "$o.png" --stats "$o.json" 2> "$o.log"
        python3 - "$o.json" "$mesh" "$light" "$n" "$m" >> "$CSV" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); r = s['reference']
cycles = s['light']['cycles'] + ((s.get('refine') or {}).get('cycles') or 0)
print(f"{sys.argv[2]},\"{sys.argv[3]}\",{sys.argv[4]},{sys.argv[5]},{r['shadow_disagreement_pct']:.2f},{r['psnr_db']:.2f},{cycles}")
PY
      done
    done
   done
  done
done
. bench/lib.sh
{
  bench_header "NS=\"$NS\" METHODS=\"$METHODS\" ROTATE=\"$ROTATE\"${APPEND:+ APPEND=$APPEND} bash bench/unseen.sh"
  echo
  python3 - "$CSV" "$METHODS" <<'PY'
import csv, sys, collections
rows = list(csv.DictReader(open(sys.argv[1])))
order = sys.argv[2].split()
label = {"exact": "diffusion, exact occluders (the default)", "plane": "diffusion, plane rule",
         "classic": "classic shadow rays, exact", "classic-plane": "classic shadow rays, plane rule",
         "refined": "refined edges"}
meshes = list(dict.fromkeys(r["mesh"].split("-")[0] for r in rows))
by = collections.defaultdict(list)
for r in rows:
    by[(int(r["n"]), r["method"])].append(r)
print("| n | method | " + " | ".join(meshes) + f" | all {max(len(v) for v in by.values())}: mean / worst | worst PSNR | mean cycles |")
print("|---|---|" + "---|" * (len(meshes) + 3))
pct = lambda rs: [float(r["shadow_disagreement_pct"]) for r in rs]
for (n, m) in sorted(by, key=lambda k: (k[0], order.index(k[1]) if k[1] in order else 99)):
    rs = by[(n, m)]
    cells = []
    for mesh in meshes:
        d = pct([r for r in rs if r["mesh"].split("-")[0] == mesh])
        cells.append(f"{sum(d) / len(d):.2f} / {max(d):.2f} %" if d else "–")
    d = pct(rs)
    cyc = sum(int(r["cycles"]) for r in rs) / len(rs)
    print(f"| {n} | {label.get(m, m)} | " + " | ".join(cells) +
          f" | {sum(d) / len(d):.2f} / {max(d):.2f} % | {min(float(r['psnr_db']) for r in rs):.1f} dB | {cyc:,.0f} |".replace(",", " "))
PY
} | tee bench-out/unseen.md
