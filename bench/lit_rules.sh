#!/usr/bin/env bash
# The lit rules against the f64 reference (thesis §5.5.5–5.5.6): for each scene and n, render
# with exact occluders (the default), the plane rule and the thesis's rule, by beam diffusion
# and by classic shadow rays, and collect shadow disagreement, PSNR, cycles, beams and wall time.
# Each scene in its default view (the Cornell box through its published camera).
# Configurations (METHODS, default all but exact-voxel):
#   exact           the defaults: exact occluders, target rays, rays from the light (the three
#                   parts of exact shadow edges); standard + conservative surfaces, f = 0, radial
#   plane           --lit-rule plane --rays-from voxel (the former default)
#   plane-f1        the same with --frac-bits 1 (twice the rays per axis: the accuracy knob)
#   thesis          --lit-rule thesis --rays-from voxel on the same surfaces, f and policy
#   thesis-thin     --lit-rule thesis with the thesis's setup (naive + projected, f = 0,
#                   wavefront, rays from the source voxel): the figures the project used to quote
#   classic         --lighting classic (shadow rays from the visible surface, each tested
#                   against the triangles of the columns it crosses: exact occluders)
#   classic-plane   --lighting classic --lit-rule plane (the plane principle)
#   classic-thesis  --lighting classic --lit-rule thesis (from voxel centres, the thesis's test)
#   refined         --lighting refined: the defaults, then one classic shadow ray (exact
#                   occluders) from each pixel on a diffused shadow's edge (cycles: both phases)
#   exact-voxel     exact occluders with the thesis's rays (from the source voxel)
# NS (default "128 256") and SCENES (default "cornell teapot-floor cow-floor bureau1") choose the
# runs; TAG names a separate set of outputs (bench-out/lit-rules-TAG.*). Writes
# bench-out/lit-rules.csv (one line per run) and bench-out/lit-rules.md: BENCHMARKS.md's two
# tables (cycles and light-phase seconds; shadow disagreement and PSNR against the reference),
# one column per method in METHODS order, with the command, commit, machine and date.
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"128 256"}
SCENES=${SCENES:-"cornell teapot-floor cow-floor bureau1"}
METHODS=${METHODS:-"exact plane plane-f1 thesis thesis-thin classic classic-plane classic-thesis"}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=./target/release/host-sim
CSV=bench-out/lit-rules${TAG:+-$TAG}.csv
MD=${CSV%.csv}.md
[[ ${APPEND:-0} == 1 && -f $CSV ]] || echo "scene,n,method,cycles,beams_or_rays,shadow_disagreement_pct,psnr_db,light_s,wall_s" > "$CSV"
for n in $NS; do
  for scene in $SCENES; do
    for m in $METHODS; do
      case $m in
        plane) opts=(--lit-rule plane --rays-from voxel) ;;
        plane-f1) opts=(--lit-rule plane --rays-from voxel --frac-bits 1) ;;
        thesis) opts=(--lit-rule thesis --rays-from voxel) ;;
        thesis-thin) opts=(--lit-rule thesis --rays-from voxel --sigma naive --contour projected --frac-bits 0 --policy wavefront) ;;
        classic) opts=(--lighting classic) ;;
        classic-plane) opts=(--lighting classic --lit-rule plane) ;;
        classic-thesis) opts=(--lighting classic --lit-rule thesis) ;;
        exact) opts=() ;;
        refined) opts=(--lighting refined) ;;
        exact-voxel) opts=(--lit-rule exact --rays-from voxel) ;;
        *) echo "unknown method $m" >&2; exit 2 ;;
      esac
      o=bench-out/lit-$scene-$n-$m
      $B render "$scene" --n "$n" --reference --quiet "${opts[@]}" --out "$o.png" --stats "$o.json" 2> "$o.log"
      python3 - "$o.json" "$scene" "$n" "$m" >> "$CSV" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); l = s['light']; r = s['reference']
work = l.get('beams_processed') or l.get('rays') or 0
cycles = l['cycles'] + ((s.get('refine') or {}).get('cycles') or 0)
print(f"{sys.argv[2]},{sys.argv[3]},{sys.argv[4]},{cycles},{work},{r['shadow_disagreement_pct']:.2f},"
      f"{r['psnr_db']:.2f},{s['light_seconds']:.2f},{s['wall_seconds']:.2f}")
PY
      tail -1 "$CSV"
    done
  done
done
. bench/lib.sh
{
  bench_header "${TAG:+TAG=$TAG }NS=\"$NS\" SCENES=\"$SCENES\" METHODS=\"$METHODS\" bash bench/lit_rules.sh"
  python3 - "$CSV" "$METHODS" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
methods = sys.argv[2].split()
label = {
    "exact": "exact occluders (the default)", "plane": "plane rule", "plane-f1": "plane rule, f = 1",
    "thesis": "thesis's rule, same surfaces", "thesis-thin": "the thesis's machine",
    "classic": "classic rays, exact", "classic-plane": "classic rays, plane rule",
    "classic-thesis": "classic rays, thesis's rule", "refined": "refined edges",
    "exact-voxel": "exact, rays from the voxel",
}
keys = list(dict.fromkeys((r["scene"], r["n"]) for r in rows))
at = {(r["scene"], r["n"], r["method"]): r for r in rows}
def table(title, cell, extra=None):
    print(f"\n{title}\n")
    cols = [label.get(m, m) for m in methods] + ([extra[0]] if extra else [])
    print("| scene | n | " + " | ".join(cols) + " |")
    print("|---|---|" + "---|" * len(cols))
    for k in keys:
        cells = [cell(at[k + (m,)]) if k + (m,) in at else "–" for m in methods]
        if extra:
            cells.append(extra[1](k))
        print(f"| {k[0]} | {k[1]} | " + " | ".join(cells) + " |")
def ratio(k):
    a, b = at.get(k + ("exact",)), at.get(k + ("thesis-thin",))
    return f"{int(a['cycles']) / int(b['cycles']):.2f}" if a and b else "–"
table("Light cycles / host seconds of the light phase (cycles are exact; seconds from one run on a shared machine):",
      lambda r: f"{int(r['cycles']):,} / {float(r['light_s']):.1f} s".replace(",", " "),
      ("default / thesis's machine, cycles", ratio) if {"exact", "thesis-thin"} <= set(methods) else None)
table("Shadow disagreement against the f64 reference (% of the (pixel, light) pairs covered in both) / PSNR:",
      lambda r: f"{r['shadow_disagreement_pct']} % / {float(r['psnr_db']):.1f} dB")
PY
} | tee "$MD"
