#!/usr/bin/env bash
# Form-factor methods against one truth (radiosity thesis ch. 2): each projective surface at
# the resolution Table 2.1's criterion makes equivalent to a hemicube of R (the same precision
# budget), the reference's default estimator (`beams`: exact contour integral × ray-cast
# visibility, 3 × 3 points per patch triangle) and the grid's own beam shots, all on the same
# patches, each compared per patch with a converged truth (`radiosity --truth-error`: the
# contour estimator at 6 × 6 points per triangle, a tenth of the residual), on the reflected
# radiosity. Cost: the f64 reference's wall seconds (the grid's: its simulation's).
#
# Usage: bench/ff_accuracy.sh BIN   (env SCENE=cornell, N=64, RS="16 32 64", RESIDUAL=0.01,
#                                    OUT=bench-out/ff_accuracy.csv; the table goes to
#                                    ${OUT%.csv}.md, the plot to ${OUT%.csv}.png)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/ff_accuracy.sh BIN" >&2; exit 2; }
BIN=$(realpath "$1")
SCENE=${SCENE:-cornell}
N=${N:-64}
RS=${RS:-16 32 64}
RESIDUAL=${RESIDUAL:-0.01}
OUT=${OUT:-bench-out/ff_accuracy.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

"$BIN" form-factors --figure "$WORK/fig.png" --figure-csv "$WORK/eq.csv" > /dev/null 2>&1
# The resolution of METHOD equivalent to hemicube R (the figure CSV: every even R in 16..=96).
res() { awk -F, -v m="$1" -v r="$2" 'NR > 1 && $3 == m && $4 == r { print $5; exit }' "$WORK/eq.csv"; }

run() { # method, hemicube R (or -), form-factors spec
  "$BIN" radiosity "$SCENE" --n "$N" --residual "$RESIDUAL" --reference --truth-error --form-factors "$3" \
    --stats "$WORK/s.json" --patches-csv "$WORK/p.csv" --shots-csv "$WORK/sh.csv" \
    --residual-plot "$WORK/r.png" --quiet > "$WORK/log" 2>&1 || { tail -20 "$WORK/log" >&2; exit 1; }
  python3 - "$WORK/s.json" "$SCENE" "$N" "$1" "$2" "$3" >> "$OUT" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
r, t = s["reference"], s["reference"]["truth"]
scene, n, method, hr, spec = sys.argv[2:]
print(f"{scene},{n},{s['patches']},{method},{hr},{spec},{r['wall_seconds']:.4f},{t['reference_rms_relative_error']:.6f},"
      f"{s['wall_seconds']:.4f},{t['machine_rms_relative_error']:.6f},{t['shots']},{t['wall_seconds']:.3f}")
PY
  tail -1 "$OUT" >&2
}

echo "scene,n,patches,method,hemicube_r,form_factors,reference_seconds,reference_error,machine_seconds,machine_error,truth_shots,truth_seconds" > "$OUT"
run beams - beams
for r in $RS; do
  for m in hemicube sillion recker hemisphere-uniform hemisphere disk; do
    d=$(res "$m" "$r")
    [ -n "$d" ] || { echo "no $m resolution equivalent to hemicube R = $r (even R in 16..=96)" >&2; exit 1; }
    run "$m" "$r" "$m:$d"
  done
done

# Table and plot (matplotlib in a venv under bench-out/, not a dependency of the product).
VENV=$REPO/bench-out/venv
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/python" -c "import matplotlib" 2> /dev/null || "$VENV/bin/pip" install -q matplotlib
"$VENV/bin/python" - "$OUT" "${OUT%.csv}.png" "$(git -C "$REPO" rev-parse --short HEAD)$(git -C "$REPO" diff --quiet HEAD || echo " + uncommitted changes")" \
  "$("$BIN" --version)" "$(nproc)" "$SCENE" "$N" "$RS" "$RESIDUAL" > "${OUT%.csv}.md" <<'PY'
import csv, datetime, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
rows = list(csv.DictReader(open(sys.argv[1])))
png, commit, version, cores, scene, n, rs, residual = sys.argv[2:]
now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
print(f'`SCENE={scene} N={n} RS="{rs}" RESIDUAL={residual} bash bench/ff_accuracy.sh BIN` ({version}, commit {commit}), '
      f"{now}, {cores} cores; {rows[0]['patches']} patches; errors: area-weighted RMS relative difference of the "
      f"reflected radiosity from the truth (contour estimator, 6 × 6 points per triangle, {rows[0]['truth_shots']} shots):")
print()
print("| method | hemicube R | form factors | reference s | error vs truth |")
print("|---|---|---|---|---|")
for r in rows:
    print(f"| {r['method']} | {r['hemicube_r']} | `{r['form_factors']}` | {float(r['reference_seconds']):.2f} | "
          f"{100 * float(r['reference_error']):.2f} % |")
g = rows[0]
print(f"| the grid's beam shots (n = {n}) | – | – | {float(g['machine_seconds']):.2f} (simulation) | "
      f"{100 * float(g['machine_error']):.2f} % |")
fig, ax = plt.subplots(figsize=(7.5, 5))
for m in dict.fromkeys(r["method"] for r in rows[1:]):
    pts = sorted((float(r["reference_seconds"]), float(r["reference_error"]), r["hemicube_r"]) for r in rows if r["method"] == m)
    ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=m)
ax.plot([float(g["reference_seconds"])], [float(g["reference_error"])], "ks", label="beams (contour × visibility, 3 × 3)")
ax.plot([float(g["machine_seconds"])], [float(g["machine_error"])], "r*", ms=12, label=f"the grid (n = {n}, simulated)")
ax.set_xscale("log"); ax.set_yscale("log")
ax.set_xlabel(f"host seconds (the grid: its simulation); points at hemicube R = {rs} equivalents")
ax.set_ylabel("per-patch RMS relative error vs the converged truth")
ax.set_title(f"{scene}, {g['patches']} patches: error against cost")
ax.grid(True, which="both", alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(png, dpi=110)
PY
cat "${OUT%.csv}.md"
echo "plot: ${OUT%.csv}.png"
