#!/usr/bin/env bash
# The thesis's diffusion experiment (§4.4.3): empty N³ scene, one source at the centre, f = 0;
# T (cycles until the last beam is consumed) for each N, FIFO size FA and policy, beside the
# thesis's published T where it gives one; then the fitted growth exponents of T in N.
# Usage: bash bench/diffusion.sh   (~3 minutes on 2 cores; NS and FAS override the grid)
# Writes bench-out/diffusion-table.{csv,png} and bench-out/diffusion-table.md (BENCHMARKS.md's
# two tables, with command, commit, machine and date).
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-16,32,64,128}
FAS=${FAS:-1,2,4,8,16,32,64}
mkdir -p bench-out
cargo build --release -q -p host-sim
./target/release/host-sim diffusion-table --n "$NS" --fa "$FAS" --policy thesis,wavefront,radial \
  --out bench-out/diffusion-table.csv --plot bench-out/diffusion-table.png --quiet > /dev/null
. bench/lib.sh
{
  bench_header "NS=$NS FAS=$FAS bash bench/diffusion.sh"
  python3 - <<'PY'
import csv, math
rows = list(csv.DictReader(open("bench-out/diffusion-table.csv")))
at = {(int(r["n"]), int(r["fa"]), r["policy"]): r for r in rows}
sp = lambda x: f"{int(x):,}".replace(",", " ")
print("\nT per policy, (T/LB) in brackets; LB = max(largest layer + 1, most beams one cell processes):\n")
print("| N | FA | thesis §4.4.3 (published) T | ours, thesis policy | ours, wavefront + merge | ours, radial + merge (the default) |")
print("|---|---|---|---|---|---|")
for (n, fa) in sorted({(k[0], k[1]) for k in at}):
    pub = next((r["thesis_t"] for p in ("thesis", "wavefront", "radial") for r in [at.get((n, fa, p))] if r and r["thesis_t"]), "")
    if not pub and fa not in (1, 16, 32):
        continue
    cells = [f"{sp(r['cycles'])} ({float(r['t_over_lb']):.2f})" if r else "–"
             for r in (at.get((n, fa, p)) for p in ("thesis", "wavefront", "radial"))]
    print(f"| {n} | {fa} | {sp(pub) if pub else '–'} | " + " | ".join(cells) + " |")
def slope(pts):
    xs = [math.log(n) for n, _ in pts]; ys = [math.log(t) for _, t in pts]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
print("\nFitted exponent of T in N (least squares over the grid sizes run):\n")
print("| policy | FA | T at each N | exponent |")
print("|---|---|---|---|")
thesis_fa1 = [(16, 345), (32, 1315), (64, 5537), (128, 20556)]
print(f"| thesis §4.4.3 (published) | 1 | {', '.join(sp(t) for _, t in thesis_fa1)} | {slope(thesis_fa1):.2f} |")
for pol in ("thesis", "wavefront", "radial"):
    for fa in (1, 16, 64):
        pts = sorted((int(r["n"]), int(r["cycles"])) for r in rows if r["policy"] == pol and int(r["fa"]) == fa)
        if len(pts) >= 2:
            print(f"| ours, {pol} | {fa} | {', '.join(sp(t) for _, t in pts)} | {slope(pts):.2f} |")
PY
} | tee bench-out/diffusion-table.md
