#!/usr/bin/env bash
# What a cell costs in RAM (thesis §4.3.2): `host-sim audit SCENE --n N` for each scene and n —
# the stores of the cell the host and the firmware compile (`cell_core::cell`'s capacities) with
# what the shipped render adds (the column's triangle store for exact occluders, the 32-block
# occupancy summary of the hidden-voxel skip), and what each scene actually used (peak dexels,
# FIFO, lit runs, triangles) with the cell those peaks would need.
#   SCENES default: "cornell teapot-floor bureau1 bureau2 ../shared/scenes/fandisk.obj"
#   NS     default: "128 256"
# Writes bench-out/cell_cost.csv and bench-out/cell_cost.md (BENCHMARKS.md's two tables, with
# command, commit, machine and date). ~1 minute on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENES=${SCENES:-"cornell teapot-floor bureau1 bureau2 ../shared/scenes/fandisk.obj"}
NS=${NS:-"128 256"}
mkdir -p bench-out/cell_cost
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/cell_cost.csv
echo "scene,n,static_dexel_store,static_fifo,static_output_buffers,static_lit_runs,bytes_row_packet,static_total,triangle_store,summary_32,used_dexels,used_fifo,used_lit_runs,used_triangles,needed_total" > "$CSV"
for n in $NS; do
  for scene in $SCENES; do
    j=bench-out/cell_cost/$(basename "$scene" .obj)-$n.json
    $B audit "$scene" --n "$n" --json "$j" > /dev/null
    python3 - "$j" "$(basename "$scene" .obj)" >> "$CSV" <<'PY'
import json, sys
a = json.load(open(sys.argv[1]))
print(",".join(str(x) for x in [sys.argv[2], a["n"], a["static_dexel_store"], a["static_fifo"], a["static_output_buffers"],
      a["static_lit_runs"], a["bytes_row_packet"], a["static_total"], a["triangle_store"], a["frustum_summary"][2],
      a["used_dexels"], a["used_fifo"], a["used_lit_runs"], a["used_triangles"], a["needed_total"]]))
PY
  done
done
. bench/lib.sh
{
  bench_header "SCENES=\"$SCENES\" NS=\"$NS\" bash bench/cell_cost.sh"
  python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
r = rows[0]
total = int(r["static_total"]) + int(r["triangle_store"]) + int(r["summary_32"])
print("\nThe cell `host-sim render` simulates by default (the capacities of `cell_core::cell`, code excluded):\n")
print("| part | bytes |\n|---|---|")
for name, key in [("dexel store", "static_dexel_store"), ("FIFO", "static_fifo"), ("output buffers", "static_output_buffers"),
                  ("lit runs", "static_lit_runs"), ("inbound row packet", "bytes_row_packet")]:
    print(f"| {name} | {int(r[key]):,} |".replace(",", " "))  # names carry no comma
sp = lambda x: f"{int(x):,}".replace(",", " ")
print(f"| column's triangle store (exact occluders) | {sp(r['triangle_store'])} |")
print(f"| occupancy summary, 32 blocks (hidden-voxel skip) | {sp(r['summary_32'])} |")
print(f"| **total** | **{sp(total)}** |")
print("\nWhat each scene used (peaks over its cells), and the cell compiled with exactly those peaks (without the triangle store and summary):\n")
print("| scene | n | peak dexels | peak FIFO | peak lit runs | peak triangles in a column | cell with those peaks |")
print("|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['scene']} | {r['n']} | {r['used_dexels']} | {r['used_fifo']} | {r['used_lit_runs']} | {r['used_triangles']} | {int(r['needed_total']):,} B |".replace(",", " "))
PY
} | tee bench-out/cell_cost.md
