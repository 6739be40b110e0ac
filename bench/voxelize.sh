#!/usr/bin/env bash
# Benchmark `host-sim voxelize`: wave vs direct engine, fandisk and a ~70k-triangle mesh,
# n = 256 and 512. Each configuration runs REPS times; the CSV keeps every run, the summary
# prints medians (BENCHMARKS.md's table, with command, commit, machine and date; also written to
# OUT with .md for .csv). Usage: bash bench/voxelize.sh [OUT.csv]   (default bench-out/voxelize.csv)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-bench-out/voxelize.csv}
REPS=${REPS:-5}
mkdir -p "$(dirname "$OUT")" bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
[ -f bench-out/cow70k.obj ] || $B subdivide cow --target 70000 --out bench-out/cow70k.obj
echo "scene,n,engine,rep,facets,voxels,load_cycles,precompute_s,load_s,wall_s,peak_rss_mib" > "$OUT"
for scene in fandisk bench-out/cow70k.obj; do
  for n in 256 512; do
    for engine in wave direct; do
      for rep in $(seq 1 "$REPS"); do
        $B voxelize "$scene" --n "$n" --engine "$engine" --quiet --out bench-out/tmp.binvox \
           --stats bench-out/tmp.json 2>/dev/null
        python3 - "$scene" "$n" "$engine" "$rep" >> "$OUT" <<'PY'
import json, sys, os
s = json.load(open("bench-out/tmp.json"))
scene = os.path.basename(sys.argv[1]).removesuffix(".obj")
print(",".join(map(str, [scene, sys.argv[2], sys.argv[3], sys.argv[4], s["facets"], s["voxels"],
    s["load_cycles"], round(s["precompute_seconds"], 4), round(s["load_seconds"], 4),
    round(s["wall_seconds"], 4), round(s["peak_rss_mib"] or 0, 1)])))
PY
      done
    done
  done
done
. bench/lib.sh
{
bench_header "REPS=$REPS bash bench/voxelize.sh"
echo
python3 - "$OUT" <<'PY'
import csv, sys, statistics as st
rows = list(csv.DictReader(open(sys.argv[1])))
key = lambda r: (r["scene"], int(r["n"]))
print("| scene | n | facets | voxels | wave load cycles | wave wall s (median) | direct wall s (median) | wave / direct | peak RSS MiB wave / direct |")
print("|---|---|---|---|---|---|---|---|---|")
for k in sorted({key(r) for r in rows}):
    g = {e: [r for r in rows if key(r) == k and r["engine"] == e] for e in ("wave", "direct")}
    w = st.median(float(r["wall_s"]) for r in g["wave"]); d = st.median(float(r["wall_s"]) for r in g["direct"])
    rw = max(float(r["peak_rss_mib"]) for r in g["wave"]); rd = max(float(r["peak_rss_mib"]) for r in g["direct"])
    r0 = g["wave"][0]
    print(f"| {k[0]} | {k[1]} | {r0['facets']} | {r0['voxels']} | {r0['load_cycles']} | {w:.3f} | {d:.3f} | {w/d:.2f} | {rw:.0f} / {rd:.0f} |")
PY
} | tee "${OUT%.csv}.md"
