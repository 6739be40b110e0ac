#!/usr/bin/env bash
# The thesis's diffusion experiment (§4.4.3): empty N³ scene, one source at the centre,
# T for each N, FIFO size FA and policy; then the fitted growth exponents of T in N.
# Usage: bash bench/diffusion.sh        (writes bench-out/diffusion-table.{csv,png})
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p bench-out
cargo build --release -q -p host-sim
./target/release/host-sim diffusion-table --n 16,32,64,128 --fa 1,2,4,8,16,32,64 \
  --out bench-out/diffusion-table.csv --plot bench-out/diffusion-table.png --quiet
python3 - <<'PY'
import csv, math
rows = list(csv.DictReader(open("bench-out/diffusion-table.csv")))
def slope(pts):
    xs = [math.log(n) for n, _ in pts]; ys = [math.log(t) for _, t in pts]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
print("| policy | FA | T at N = 16, 32, 64, 128 | fitted exponent of T in N |")
print("|---|---|---|---|")
for pol in ("thesis", "wavefront"):
    for fa in sorted({int(r["fa"]) for r in rows}):
        pts = sorted((int(r["n"]), int(r["cycles"])) for r in rows if r["policy"] == pol and int(r["fa"]) == fa)
        print(f"| {pol} | {fa} | {', '.join(str(t) for _, t in pts)} | {slope(pts):.2f} |")
thesis_fa1 = [(16, 345), (32, 1315), (64, 5537), (128, 20556)]
print(f"| thesis §4.4.3 (published) | 1 | {', '.join(str(t) for _, t in thesis_fa1)} | {slope(thesis_fa1):.2f} |")
PY
