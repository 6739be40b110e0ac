#!/usr/bin/env bash
# What the default cell must hold: `host-sim audit` (the cell `render` runs by default: exact
# occluders, rays from the light, the radial policy, the visible-only lit store, the skips) on
# the held-out meshes under the held-out lights (bench/unseen.sh's) and on the built-in scenes
# under their own lights, at each n of NS. For each run: the peak dexels, FIFO beams, lit runs
# and triangles of any one cell (and which cell), and the RAM of a cell cut to those
# capacities: the audit's "needed" total (dexels, FIFO, output buffers, lit runs, the inbound
# row packet) plus the column's triangles and the occupancy summary of `render`'s 32 blocks.
# Writes bench-out/cell_capacities.csv and bench-out/cell_capacities.md (a table for
# BENCHMARKS.md, "RAM of the firmware images"), the last line the maximum over every run.
#
#   bash bench/cell_capacities.sh [HOST_SIM]       (default target/release/host-sim, built)
#   MESHES  default: suzanne fandisk cow teapot (../shared/scenes/NAME.obj)
#   LIGHTS  default: 0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9
#   SCENES  default: cornell teapot-floor bureau1 (built-in, their own lights)
#   NS      default: 256
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/lib.sh
BIN=${1:-target/release/host-sim}
if [[ $# -eq 0 ]]; then cargo build --release -q -p host-sim; fi
MESHES=${MESHES:-"suzanne fandisk cow teapot"}
LIGHTS=${LIGHTS:-"0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9"}
SCENES=${SCENES:-"cornell teapot-floor bureau1"}
NS=${NS:-256}
OUT=bench-out
mkdir -p "$OUT"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

runs=()
for n in $NS; do
  for m in $MESHES; do
    for l in $LIGHTS; do runs+=("$n|../shared/scenes/$m.obj|$l"); done
  done
  for s in $SCENES; do runs+=("$n|$s|"); done
done

k=0
for r in "${runs[@]}"; do
  IFS='|' read -r n scene light <<< "$r"
  args=(audit "$scene" --n "$n" --json "$tmp/$k.json")
  if [[ -n $light ]]; then args+=(--light "$light"); fi
  echo "audit $scene n=$n ${light:+light $light}" >&2
  "$BIN" "${args[@]}" > "$tmp/$k.txt" 2>&1 || {
    cat "$tmp/$k.txt" >&2
    exit 1
  }
  echo "$n|$scene|$light|$k" >> "$tmp/index"
  k=$((k + 1))
done

python3 - "$tmp" "$OUT" "$(bench_header "bash bench/cell_capacities.sh")" << 'EOF'
import json, os, sys
tmp, out, header = sys.argv[1], sys.argv[2], sys.argv[3]
rows = []
for line in open(os.path.join(tmp, "index")):
    n, scene, light, k = line.rstrip("\n").split("|")
    a = json.load(open(os.path.join(tmp, f"{k}.json")))
    name = os.path.basename(scene).removesuffix(".obj")
    tri = a["used_triangles"] * (a["triangle_store"] // 64)
    summary = a["frustum_summary"][2]
    rows.append(dict(
        n=int(n), scene=name, light=light or "own",
        dexels=a["used_dexels"], dexels_cell=a["used_dexels_cell"],
        fifo=a["used_fifo"], fifo_cell=a["used_fifo_cell"],
        lit_runs=a["used_lit_runs"], lit_runs_cell=a["used_lit_runs_cell"],
        triangles=a["used_triangles"], triangles_cell=a["used_triangles_cell"],
        left_out=a["triangle_overflows"],
        needed=a["needed_total"], triangle_bytes=tri, summary32=summary,
        ram=a["needed_total"] + tri + summary))
keys = ["n", "scene", "light", "dexels", "fifo", "lit_runs", "triangles", "left_out", "needed", "triangle_bytes", "summary32", "ram"]
with open(os.path.join(out, "cell_capacities.csv"), "w") as f:
    f.write(",".join(keys + ["dexels_cell", "triangles_cell"]) + "\n")
    for r in rows:
        cells = [f'"{r["dexels_cell"][0]} {r["dexels_cell"][1]}"', f'"{r["triangles_cell"][0]} {r["triangles_cell"][1]}"']
        f.write(",".join(str(r[k]) for k in keys) + "," + ",".join(cells) + "\n")
md = [header, "",
      "| n | scene | light | dexels | FIFO beams | lit runs | triangles (left out) | cell cut to them, B | + triangles, B | + 32-block summary, B | RAM, B |",
      "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
for r in rows:
    md.append(f'| {r["n"]} | {r["scene"]} | {r["light"]} | {r["dexels"]} | {r["fifo"]} | {r["lit_runs"]} | '
              f'{r["triangles"]} ({r["left_out"]}) | {r["needed"]} | {r["triangle_bytes"]} | {r["summary32"]} | {r["ram"]} |')
mx = {k: max(r[k] for r in rows) for k in ["dexels", "fifo", "lit_runs", "triangles", "left_out", "needed", "triangle_bytes", "summary32", "ram"]}
md.append(f'| **max** | {len(rows)} runs | | **{mx["dexels"]}** | **{mx["fifo"]}** | **{mx["lit_runs"]}** | '
          f'**{mx["triangles"]}** ({mx["left_out"]}) | {mx["needed"]} | {mx["triangle_bytes"]} | {mx["summary32"]} | **{mx["ram"]}** |')
open(os.path.join(out, "cell_capacities.md"), "w").write("\n".join(md) + "\n")
print("\n".join(md))
EOF
