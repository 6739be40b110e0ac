#!/usr/bin/env bash
# Samples per pixel (issue 54 item 5(c)): `render --samples S --sample-lights L --reference` for
# S = 1 … 4 under both light rules, each image against the reference averaging the same S × S
# points (same-way PSNR) and against the reference averaging 4 × 4 (the finest the machine
# makes: what more samples approach), with what the samples cost the machine (cycles, bytes per
# cell and packet, loading's extra row steps, the exchange's messages) and the host (shade and
# reference seconds). Writes bench-out/samples.csv and prints the markdown table of
# BENCHMARKS.md ("Samples per pixel") with its header lines; with PICTURES=1 also
# docs/samples.png (the Cornell box at n = 128, ×2: 1 sample | 4 × 4 nearest | 4 × 4 bilinear |
# the 4 × 4 reference) and docs/samples-cost.png (error against cost: PSNR against the 4 × 4
# reference over the bytes the samples add to a cell, per scene and n; Pillow and matplotlib
# through bench/venv.sh). SCENES (default "cornell teapot-floor
# bureau1") and NS (default "128 256") choose the runs; RATIO_SCENES (default "cornell
# teapot-floor") also run 1 and 4 × 4 samples under `--visibility ratio --frac-bits 2` (soft
# shadow edges lent to the samples). ~4 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
SCENES=${SCENES:-"cornell teapot-floor bureau1"}
NS=${NS:-"128 256"}
RATIO_SCENES=${RATIO_SCENES:-"cornell teapot-floor"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
. bench/venv.sh
PY=$(bench_python pillow numpy) # "import pillow" fails, so pip checks it each time (quick)
CSV=bench-out/samples.csv
echo "scene,n,samples,sample_lights,visibility,psnr_db,psnr_vs_4x4_db,shadow_disagreement_pct,load_cycles,light_cycles,shade_cycles,beams,bytes_per_cell,extra_bytes_per_cell,extra_bytes_per_packet,load_extra_row_steps,exchange_messages,mixed_pixels,shade_s,reference_s" > "$CSV"
for scene in $SCENES; do
  for n in $NS; do
    o=bench-out/samples-$scene-$n
    # The 4 × 4 reference first: every run is also compared with it.
    runs="4:bilinear:target 1:bilinear:target 2:bilinear:target 3:bilinear:target 2:nearest:target 3:nearest:target 4:nearest:target"
    case " $RATIO_SCENES " in *" $scene "*) runs="$runs 1:bilinear:ratio 4:bilinear:ratio" ;; esac
    for run in $runs; do
      IFS=: read -r s l vis <<< "$run"
      out=$o-$s-$l-$vis
      extra=()
      [ "$vis" = ratio ] && extra=(--visibility ratio --frac-bits 2)
      $B render "$scene" --n "$n" --samples "$s" --sample-lights "$l" "${extra[@]}" --reference --quiet \
        --out "$out.png" --stats "$out.json" 2> "$out.log"
      [ "$s" = 4 ] && [ "$l" = bilinear ] && [ "$vis" = target ] && cp "$out.reference.png" "$o-ref4.png"
      "$PY" - "$out.json" "$out.png" "$o-ref4.png" "$scene" "$n" "$s" "$l" "$vis" >> "$CSV" <<'PY'
import json, sys
import numpy as np
from PIL import Image
p, img, ref4, scene, n, s, l, vis = sys.argv[1:]
st = json.load(open(p)); ref = st["reference"]; sm = st.get("samples") or {}
a = np.asarray(Image.open(img).convert("RGB"), dtype=np.float64)
b = np.asarray(Image.open(ref4).convert("RGB"), dtype=np.float64)
mse = ((a - b) ** 2).mean()
psnr4 = 10 * np.log10(255.0 ** 2 / mse) if mse > 0 else float("inf")
lt = st["light"]
vis = vis if vis == "target" else "ratio f=2"
print(",".join(map(str, [scene, n, s, l if s != "1" else "-", vis, f"{ref['psnr_db']:.2f}", f"{psnr4:.2f}",
      f"{ref['shadow_disagreement_pct']:.2f}", st["light"]["load_cycles"], lt["cycles"], st["shade_cycles"],
      lt["beams_processed"], st["bytes_per_cell"], sm.get("bytes_per_cell", 0), sm.get("bytes_per_packet", 0),
      sm.get("load_extra_row_steps", 0), sm.get("exchange_messages", 0), sm.get("mixed_pixels", 0),
      f"{st['shade_seconds']:.2f}", f"{st['reference_seconds']:.2f}"])))
PY
    done
  done
done
. bench/lib.sh
bench_header "SCENES=\"$SCENES\" NS=\"$NS\" bash bench/samples.sh"
echo
python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
order = lambda r: (r["scene"], int(r["n"]), r["visibility"] != "target", int(r["samples"]), r["sample_lights"] != "bilinear")
print("| scene | n | samples | lights | visibility | PSNR dB, same-way reference | PSNR dB vs the 4 × 4 reference | shadow disagreement % | cycles load + light + shade | beams | bytes/cell (+ samples) | + bytes/packet | + row steps in loading | exchange messages | mixed pixels | shade s | reference s |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
sp = lambda v: f"{int(v):,}".replace(",", " ")
for r in sorted(rows, key=order):
    s = r["samples"]
    print(f"| {r['scene']} | {r['n']} | {s} × {s} | {r['sample_lights']} | {r['visibility']} | {r['psnr_db']} | {r['psnr_vs_4x4_db']} | "
          f"{r['shadow_disagreement_pct']} | {r['load_cycles']} + {r['light_cycles']} + {r['shade_cycles']} | {sp(r['beams'])} | "
          f"{sp(r['bytes_per_cell'])} (+{r['extra_bytes_per_cell']}) | {r['extra_bytes_per_packet']} | {sp(r['load_extra_row_steps'])} | "
          f"{sp(r['exchange_messages'])} | {sp(r['mixed_pixels'])} | {r['shade_s']} | {r['reference_s']} |")
PY
if [ "${PICTURES:-0}" = 1 ]; then
  "$PY" - <<'PY'
from PIL import Image
o = "bench-out/samples-cornell-128"
paths = [f"{o}-1-bilinear-target.png", f"{o}-4-nearest-target.png", f"{o}-4-bilinear-target.png", f"{o}-ref4.png"]
ims = [Image.open(p).convert("RGB") for p in paths]
box = (20, 40, 110, 120)  # the blocks and their shadows at n = 128 (rows top down), ×2
ims = [i.crop(box).resize((2 * (box[2] - box[0]), 2 * (box[3] - box[1])), Image.NEAREST) for i in ims]
cw, ch = ims[0].size
out = Image.new("RGB", (len(ims) * (cw + 4) - 4, ch), (255, 255, 255))
for k, i in enumerate(ims):
    out.paste(i, (k * (cw + 4), 0))
out.save("docs/samples.png", optimize=True)
PY
  ls -l docs/samples.png
fi
if [ "${PICTURES:-0}" = 1 ]; then
  MPY=$(bench_python matplotlib)
  "$MPY" - "$CSV" <<'PY'
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
rows = list(csv.DictReader(open(sys.argv[1])))
fig, ax = plt.subplots(figsize=(7.2, 4.2), dpi=100)
keys = sorted({(r["scene"], int(r["n"])) for r in rows})
for k, (scene, n) in enumerate(keys):
    colour = f"C{k}"
    for rule, style in [("bilinear", "-o"), ("nearest", ":s")]:
        pts = sorted((int(r["extra_bytes_per_cell"]), float(r["psnr_vs_4x4_db"]), r["samples"]) for r in rows
                     if r["scene"] == scene and int(r["n"]) == n and r["sample_lights"] in (rule, "-")
                     and r["visibility"] == "target")
        ax.plot([p[0] for p in pts], [p[1] for p in pts], style, color=colour, ms=4,
                label=f"{scene} n={n}" if rule == "bilinear" else None)
        if rule == "bilinear":
            for x, y, s in pts:
                ax.annotate(f"{s}×{s}", (x, y), textcoords="offset points", xytext=(3, -9), fontsize=6, color=colour)
ax.set_xlabel("bytes a cell adds for the samples (S² records + 8 neighbour messages)")
ax.set_ylabel("PSNR dB against the 4 × 4 reference")
ax.set_title("Samples per pixel: error against cost (solid: bilinear lights, dotted: nearest)", fontsize=9)
ax.grid(alpha=0.3)
ax.legend(fontsize=7, loc="lower right")
fig.tight_layout()
fig.savefig("docs/samples-cost.png")
PY
  ls -l docs/samples-cost.png
fi
