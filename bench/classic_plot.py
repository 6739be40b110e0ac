#!/usr/bin/env python3
"""Plot bench-out/classic.csv (written by bench/classic.sh): classic shadow rays against beam
diffusion (thesis §4.1.6–4.1.7).

Three panels against the grid side n, one colour per scene:
  1. link messages: diffusion (solid), classic with visible emitters (dashed), classic with
     every occupied voxel emitting (dotted, the thesis's count);
  2. machine cycles, same styles;
  3. the occupancy above which diffusion sends fewer messages than classic-all, measured, with
     the thesis's prediction 300/n % and each scene's own occupancy.

usage: python3 bench/classic_plot.py [CSV] [PNG]   (defaults bench-out/classic.csv,
       docs/classic-vs-diffusion.png); needs matplotlib (bench/classic.sh installs it in
       bench-out/venv).
"""
import csv
import sys
from collections import defaultdict

from crossover import crossover

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

src = sys.argv[1] if len(sys.argv) > 1 else "bench-out/classic.csv"
out = sys.argv[2] if len(sys.argv) > 2 else "docs/classic-vs-diffusion.png"
rows = list(csv.DictReader(open(src)))
if not rows:
    sys.exit(f"{src}: no rows")

by = defaultdict(dict)  # (scene, n) -> method -> row
for r in rows:
    by[(r["scene"], int(r["n"]))][r["method"]] = r
scenes = sorted({s for s, _ in by})
colours = dict(zip(scenes, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
styles = {"diffusion": "-", "classic": "--", "classic-all": ":"}

fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
for scene in scenes:
    ns = sorted(n for s, n in by if s == scene)
    for method, ls in styles.items():
        pts = [(n, by[(scene, n)][method]) for n in ns if method in by[(scene, n)]]
        if not pts:
            continue
        x = [n for n, _ in pts]
        ax[0].plot(x, [int(r["messages"]) for _, r in pts], ls, marker="o", color=colours[scene],
                   label=f"{scene} {method}")
        ax[1].plot(x, [int(r["cycles"]) for _, r in pts], ls, marker="o", color=colours[scene])
    # Crossover (bench/crossover.py).
    cross, occ = [], []
    for n in ns:
        m = by[(scene, n)]
        if "classic-all" not in m or "diffusion" not in m:
            continue
        a, d = m["classic-all"], m["diffusion"]
        cross.append((n, crossover(d, a, n)[1]))
        occ.append((n, float(a["occupancy_pct"])))
    if cross:
        ax[2].plot(*zip(*cross), "-", marker="o", color=colours[scene], label=f"{scene}: crossover")
        ax[2].plot(*zip(*occ), linestyle="none", marker="x", markersize=9, color=colours[scene],
                   label=f"{scene}: its occupancy")
all_n = sorted({n for _, n in by})
ax[2].plot(all_n, [300.0 / n for n in all_n], "k--", label="thesis 300/n %")
for a, title, ylabel in (
    (ax[0], "messages over links", "messages"),
    (ax[1], "machine cycles (one light at a time)", "cycles"),
    (ax[2], "occupancy above which diffusion wins", "occupancy %"),
):
    a.set_xscale("log", base=2)
    a.set_yscale("log")
    a.set_xticks(all_n, [str(n) for n in all_n])
    a.set_xlabel("grid side n")
    a.set_ylabel(ylabel)
    a.set_title(title)
    a.grid(True, which="both", alpha=0.3)
ax[2].yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
ax[2].yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
ax[0].legend(fontsize=7, ncol=1)
ax[2].legend(fontsize=7)
fig.suptitle("Classic shadow rays (dashed: visible emitters, dotted: every voxel) against beam diffusion (solid)")
fig.tight_layout()
fig.savefig(out, dpi=80)
print(f"wrote {out}")
