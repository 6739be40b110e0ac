#!/usr/bin/env bash
# Form-factor methods against one truth (radiosity thesis ch. 2): each projective surface at
# the resolution Table 2.1's criterion makes equivalent to a hemicube of R (the same precision
# budget), the reference's default estimator (`beams`: exact contour integral × ray-cast
# visibility, 3 × 3 points per patch triangle) and the grid's own beam shots, all on the same
# patches, each compared per patch with a converged truth (`radiosity --truth-error`: the
# contour estimator at 6 × 6 points per triangle, a tenth of the residual), on the reflected
# radiosity, and the image each solution renders (`render --radiosity --truth-error`: the same
# shots, display, exposure and direct light; PSNR against the truth's image). Cost: the f64
# reference's samples (the contour estimator's visibility rays, a projective surface's proxels
# at every shooter point; the grid's: the beams its shots processed) and wall seconds (the
# grid's: its simulation's).
#
# Usage: bench/ff_accuracy.sh BIN   (env SCENE=cornell, N=64, RS="16 32 64", RESIDUAL=0.01,
#                                    SHOTS= (a shot budget, e.g. 30 for bureau1's 8 038
#                                    patches), IMAGE=1 (0: per-patch errors only, through the
#                                    `radiosity` job, the truth solved once and read back from
#                                    --truth-cache), OUT=bench-out/ff_accuracy.csv; the table
#                                    goes to ${OUT%.csv}.md, the plot to ${OUT%.csv}.png)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/ff_accuracy.sh BIN" >&2; exit 2; }
BIN=$(realpath "$1")
SCENE=${SCENE:-cornell}
N=${N:-64}
RS=${RS:-16 32 64}
RESIDUAL=${RESIDUAL:-0.01}
SHOTS=${SHOTS:-}
IMAGE=${IMAGE:-1}
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
  local solve=(--n "$N" --residual "$RESIDUAL" ${SHOTS:+--shots "$SHOTS"} --reference --truth-error --form-factors "$3")
  if [ "$IMAGE" = 1 ]; then
    "$BIN" render "$SCENE" --radiosity "${solve[@]}" --out "$WORK/img.png" --stats "$WORK/s.json" --quiet
  else
    "$BIN" radiosity "$SCENE" "${solve[@]}" --truth-cache "$WORK/truth.json" --stats "$WORK/s.json" \
      --patches-csv "$WORK/p.csv" --shots-csv "$WORK/sh.csv" --residual-plot "$WORK/r.png" --quiet
  fi > "$WORK/log" 2>&1 || { tail -20 "$WORK/log" >&2; exit 1; }
  python3 - "$WORK/s.json" "$SCENE" "$N" "$1" "$2" "$3" >> "$OUT" <<'PY'
import json, sys
stats = json.load(open(sys.argv[1]))
rad = stats.get("radiosity")
s = rad["solution"] if rad else stats
img = rad["truth_image"] if rad else {"reference_psnr_db": float("nan"), "machine_psnr_db": float("nan")}
r, t = s["reference"], s["reference"]["truth"]
scene, n, method, hr, spec = sys.argv[2:]
print(f"{scene},{n},{s['patches']},{method},{hr},{spec},{r['wall_seconds']:.4f},{t['reference_rms_relative_error']:.6f},"
      f"{s['wall_seconds']:.4f},{t['machine_rms_relative_error']:.6f},{t['shots']},{t['wall_seconds']:.3f},"
      f"{r['rays_cast']},{r['proxels']},{s['beams_processed']},{img['reference_psnr_db']:.3f},{img['machine_psnr_db']:.3f}")
PY
  tail -1 "$OUT" >&2
}

echo "scene,n,patches,method,hemicube_r,form_factors,reference_seconds,reference_error,machine_seconds,machine_error,truth_shots,truth_seconds,reference_rays,reference_proxels,machine_beams,reference_psnr_db,machine_psnr_db" > "$OUT"
run beams - beams
for r in $RS; do
  for m in hemicube sillion recker hemisphere-uniform hemisphere disk; do
    d=$(res "$m" "$r")
    [ -n "$d" ] || { echo "no $m resolution equivalent to hemicube R = $r (even R in 16..=96)" >&2; exit 1; }
    run "$m" "$r" "$m:$d"
  done
done

# Table and plot (matplotlib in a venv under bench-out/, not a dependency of the product).
# shellcheck source=bench/venv.sh
. "$REPO/bench/venv.sh"
"$(bench_python matplotlib)" - "$OUT" "${OUT%.csv}.png" "$(git -C "$REPO" rev-parse --short HEAD)$(git -C "$REPO" diff --quiet HEAD || echo " + uncommitted changes")" \
  "$("$BIN" --version)" "$(nproc)" "$SCENE" "$N" "$RS" "$RESIDUAL" "$SHOTS" "$IMAGE" > "${OUT%.csv}.md" <<'PY'
import csv, datetime, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
rows = list(csv.DictReader(open(sys.argv[1])))
png, commit, version, cores, scene, n, rs, residual, shots, image = sys.argv[2:]
now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
budget = f" SHOTS={shots}" if shots else ""
print(f'`SCENE={scene} N={n} RS="{rs}" RESIDUAL={residual}{budget} IMAGE={image} bash bench/ff_accuracy.sh BIN` ({version}, commit {commit}), '
      f"{now}, {cores} cores; {rows[0]['patches']} patches; errors: area-weighted RMS relative difference of the "
      f"reflected radiosity from the truth (contour estimator, 6 × 6 points per triangle, {rows[0]['truth_shots']} shots); "
      f"samples: visibility rays (beams), proxels (projective surfaces), beams processed (the grid)"
      + (f"; PSNR: the rendered image ({n} × {n}, same shots, display and direct light) against the truth's:" if image == "1" else ":"))
print()
samples = lambda r: int(r["reference_rays"]) + int(r["reference_proxels"])
psnr = lambda v: "–" if v == "nan" else f"{float(v):.1f}"
print("| method | hemicube R | form factors | samples | reference s | error vs truth | image PSNR dB |")
print("|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['method']} | {r['hemicube_r']} | `{r['form_factors']}` | {samples(r):.3g} | "
          f"{float(r['reference_seconds']):.2f} | {100 * float(r['reference_error']):.2f} % | {psnr(r['reference_psnr_db'])} |")
g = rows[0]
print(f"| the grid's beam shots (n = {n}) | – | – | {int(g['machine_beams']):.3g} beams | {float(g['machine_seconds']):.2f} "
      f"(simulation) | {100 * float(g['machine_error']):.2f} % | {psnr(g['machine_psnr_db'])} |")
fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True)
for ax, cost, grid_cost, label in (
    (axes[0], samples, lambda r: int(r["machine_beams"]), "samples: rays (beams), proxels (surfaces), beams (the grid)"),
    (axes[1], lambda r: float(r["reference_seconds"]), lambda r: float(r["machine_seconds"]), "host seconds (the grid: its simulation)"),
):
    for m in dict.fromkeys(r["method"] for r in rows[1:]):
        pts = sorted((cost(r), float(r["reference_error"])) for r in rows if r["method"] == m)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=m)
    ax.plot([cost(g)], [float(g["reference_error"])], "ks", label="beams (contour × visibility, 3 × 3)")
    ax.plot([grid_cost(g)], [float(g["machine_error"])], "r*", ms=12, label=f"the grid (n = {n}, simulated)")
    ax.set_xscale("log"); ax.set_yscale("log")
    ax.set_xlabel(label)
    ax.grid(True, which="both", alpha=0.3)
axes[0].set_ylabel("per-patch RMS relative error vs the converged truth")
axes[1].legend(fontsize=8)
fig.suptitle(f"{scene}, {g['patches']} patches{', ' + shots + ' shots' if shots else ''}: error against cost "
             f"(points at hemicube R = {rs} equivalents)")
fig.tight_layout()
fig.savefig(png, dpi=110)
PY
cat "${OUT%.csv}.md"
echo "plot: ${OUT%.csv}.png"
