#!/usr/bin/env bash
# The main job against the f64 reference: Cornell box and two meshes on a floor, default
# configuration, n = 128, 256, 512 (set NS to change). Writes bench-out/render-*.{png,json} and
# prints a table. Then the speed/accuracy sweep (Pareto) at n = 64.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"128 256 512"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
echo "| scene | n | light cycles | T/LB | shadow disagreement % | coverage disagreement % | PSNR dB | shading err max/mean (levels) | bytes/cell | wall s | peak RSS MiB |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for n in $NS; do
  for scene in cornell teapot-floor cow-floor; do
    $B render "$scene" --n "$n" --view fitted --reference --quiet --out "bench-out/render-$scene-$n.png" \
       --stats "bench-out/render-$scene-$n.json" 2>/dev/null
    python3 - "bench-out/render-$scene-$n.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); l = s["light"]; r = s["reference"]
print(f"| {l['scene']} | {l['n']} | {l['cycles']} | {l['t_over_lb']:.2f} | {r['shadow_disagreement_pct']:.2f} | "
      f"{r['coverage_disagreement_pct']:.2f} | {r['psnr_db']:.2f} | {s['shading_max_err_levels']}/{s['shading_mean_err_levels']:.3f} | "
      f"{s['bytes_per_cell']} | {s['wall_seconds']:.1f} | {s['peak_rss_mib']:.0f} |")
PY
  done
done
$B bench --n 64 --frac-bits 0,2,4 --out bench-out/bench.csv --plot bench-out/bench.png 2>&1 | tail -26
