#!/usr/bin/env bash
# Classic shadow rays against beam diffusion (thesis §4.1.6–4.1.7): for each scene and
# n, render with both methods against the f64 reference, and run the classic phase once more
# with every occupied voxel emitting (the thesis's ray count ΣS_i) to estimate the occupancy at
# which diffusion starts to win on messages. Each scene in its default view, both methods as
# `render` ships them (exact occluders). Writes bench-out/classic.csv and bench-out/classic.md
# (BENCHMARKS.md's two tables, with command, commit, machine and date).
# NS (default "64 128") and SCENES choose the runs; n = 256 takes minutes per scene, 512 ~10 min;
# the every-voxel classic run is skipped above ALL_MAX_N (default 128). APPEND=1 adds rows to an
# existing CSV (the table and plot then cover every row). EXTRA adds options to both renders
# (e.g. EXTRA=--lit-visible-only for office scenes at n = 512, whose columns along a wall need
# more lit runs than LIT_CAP; the image and counts are the same).
# Then plots the table (bench/classic_plot.py, matplotlib in bench-out/venv) to $PLOT
# (default docs/classic-vs-diffusion.png). TABLE_ONLY=1 redraws the tables and the plot from the CSV.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"64 128"}
SCENES=${SCENES:-"cornell bureau1 bureau2 classe"}
# classic-all (every voxel emits) costs ~8x more per doubling of n: only up to this n.
ALL_MAX_N=${ALL_MAX_N:-128}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/classic.csv
[[ ( ${APPEND:-0} == 1 || ${TABLE_ONLY:-0} == 1 ) && -f $CSV ]] || echo "scene,n,voxels,occupancy_pct,method,rays,messages,cycles,busiest_cell_load,busiest_cell_distance,peak_link_load,peak_link_distance,peak_fifo,shadow_disagreement_pct,psnr_db,wall_s" > "$CSV"
if [[ ${TABLE_ONLY:-0} != 1 ]]; then
for n in $NS; do
  for scene in $SCENES; do
    o=bench-out/classic-$scene-$n
    $B render "$scene" --n "$n" --reference --quiet ${EXTRA:-} --out "$o-diffusion.png" --stats "$o-diffusion.json" 2> "$o-diffusion.log"
    $B render "$scene" --n "$n" --reference --quiet ${EXTRA:-} --lighting classic --out "$o-classic.png" --stats "$o-classic.json" 2> "$o-classic.log"
    rm -f "$o-all.json" "$o-all.log"
    if (( n <= ALL_MAX_N )); then
      $B light "$scene" --n "$n" --sigma naive --contour projected --quiet --lighting classic --emitters all \
        --stats "$o-all.json" 2> "$o-all.log"
    fi
    $B voxelize "$scene" --n "$n" --sigma naive --contour projected --quiet --stats "$o-vox.json" 2> /dev/null
    python3 - "$o" "$scene" "$n" >> "$CSV" <<'PY'
import json, os, re, sys
o, scene, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
def classic_line(log):
    m = re.search(r"classic: (\d+) rays[^,]*, .*?busiest cell (\d+) steps at distance (\d+); peak link load (\d+) at distance (\d+); peak FIFO (\d+)", open(log).read())
    if not m:
        sys.exit(f"no classic summary in {log}")
    return [int(g) for g in m.groups()]
voxels = json.load(open(o + "-vox.json"))["voxels"]
occ = 100.0 * voxels / n**3
for method in ("diffusion", "classic", "all"):
    if method == "all" and not os.path.exists(o + "-all.json"):
        continue
    path = o + ("-all.json" if method == "all" else f"-{method}.json")
    s = json.load(open(path))
    l = s.get("light", s)
    ref = s.get("reference") or {}
    if method == "diffusion":
        rays, cell, link, ldist, fifo = l["beams_processed"], l["lb_cell_load"], l["peak_link_load"], l["peak_link_distance"], l["peak_fifo"]
        bx, by = l["sources"][0]["busiest_cell"]
        sx, sy = (int(c + 0.5) for c in l["sources"][0]["position"][:2])
        cdist = max(abs(bx - sx), abs(by - sy))
    else:
        rays, cell, cdist, link, ldist, fifo = classic_line(o + ("-all.log" if method == "all" else "-classic.log"))
    print(f"{scene},{n},{voxels},{occ:.3f},{'classic-all' if method == 'all' else method},{rays},{l['messages']},{l['cycles']},"
          f"{cell},{cdist},{link},{ldist},{fifo},{ref.get('shadow_disagreement_pct', '')},{ref.get('psnr_db', '')},{l['wall_seconds']:.2f}")
PY
  done
done
fi
. bench/lib.sh
{
bench_header "NS=\"$NS\" SCENES=\"$SCENES\" ALL_MAX_N=$ALL_MAX_N${EXTRA:+ EXTRA=\"$EXTRA\"}${APPEND:+ APPEND=$APPEND} bash bench/classic.sh"
echo
python3 - "$CSV" <<'PY'
import csv, sys
sys.path.insert(0, "bench")
from crossover import crossover
rows = list(csv.DictReader(open(sys.argv[1])))
fmt = lambda x: f"{float(x):.2f}" if x else "–"
by = {}
for r in rows:
    by.setdefault((r["scene"], int(r["n"])), {})[r["method"]] = r
print("| scene | n | occupancy % | method | rays (diffusion: beams) | messages | cycles | busiest cell load (distance) | peak link load (distance) | shadow disagreement % | PSNR dB |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for (scene, n), m in by.items():
    for k in ("diffusion", "classic", "classic-all"):
        if k not in m:
            continue
        r = m[k]
        dist = lambda a, b: f"{r[a]} ({r[b]})" if r[b] else r[a]
        print(f"| {scene} | {n} | {float(r['occupancy_pct']):.2f} | {k} | {r['rays']} | {r['messages']} | {r['cycles']} | "
              f"{dist('busiest_cell_load', 'busiest_cell_distance')} | {dist('peak_link_load', 'peak_link_distance') or '–'} | "
              f"{fmt(r['shadow_disagreement_pct'])} | {fmt(r['psnr_db'])} |")
print()
print("| scene | n | occupancy % | messages per classic ray | diffusion messages | diffusion wins on messages above occupancy % | thesis 300/n % |")
print("|---|---|---|---|---|---|---|")
for (scene, n), m in by.items():
    if "classic-all" not in m:
        continue
    a, d = m["classic-all"], m["diffusion"]
    per, cross = crossover(d, a, n)
    print(f"| {scene} | {n} | {float(a['occupancy_pct']):.2f} | {per:.1f} | {d['messages']} | {cross:.2f} | {300 / n:.2f} |")
PY
} | tee bench-out/classic.md
# The plot (matplotlib in a venv under bench-out/, not a dependency of the product).
# shellcheck source=bench/venv.sh
. "$(dirname "$0")/venv.sh"
"$(bench_python matplotlib)" bench/classic_plot.py "$CSV" "${PLOT:-docs/classic-vs-diffusion.png}"
