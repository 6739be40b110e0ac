#!/usr/bin/env bash
# Shots by projection on the grid (radiosity thesis §6.2) against shots by beam diffusion
# (ch. 5): `host-sim radiosity SCENE --shots-by beams|proxels-hemicube|proxels-disk|hybrid` on the same
# patches to the same residual, one row per (scene, n, method): shots, cycles and messages per
# shot and in all, the projection's phases, bytes per cell, the SIMD yield, and with a
# reference the per-patch RMS error against the f64 solver. Then every update strategy's
# cycles per shot (§6.2.6) on the same runs; the thesis's own update figures are
# bench/proxel_router.sh's.
#
# Usage: bench/proxel_shots.sh BIN   (env ROWS="scene:n:residual:reference(0|1) ...";
#        METHODS="beams proxels-hemicube proxels-disk hybrid";
#        THREADS=2;
#        OUT=bench-out/proxel_shots.csv, markdown in ${OUT%.csv}.md)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/proxel_shots.sh BIN" >&2; exit 2; }
BIN=$(realpath -e "$1")
ROWS=${ROWS:-"cornell:32:0.01:1 cornell:64:0.01:1 bureau1:32:0.05:0 bureau2:32:0.05:0 classe:32:0.05:0"}
THREADS=${THREADS:-2}
METHODS=${METHODS:-"beams proxels-hemicube proxels-disk hybrid"}
OUT=${OUT:-bench-out/proxel_shots.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
UPD="xnet-proxels xnet-modulo xnet-facets router-proxels router-modulo reduce"
echo "scene,n,patches,shots_by,resolution,residual_target,shots,residual,cycles_per_shot,messages_per_shot,cycles,select_cycles_per_shot,projection_cycles_per_shot,update_cycles_per_shot,triangles_per_shot,bytes_per_cell,zone_yield,rect_yield,rms_vs_reference,wall_seconds,$(echo $UPD | sed 's/-/_/g; s/\([a-z_]*\)/update_\1/g; s/ /,/g'),command" > "$OUT"
run() { # scene n method residual reference [extra args...]
  local scene=$1 n=$2 method=$3 res=$4 ref=$5; shift 5
  local args=(radiosity "$scene" --n "$n" --shots-by "$method" --residual "$res" --threads "$THREADS" --quiet "$@")
  [ "$ref" = 1 ] && args+=(--reference)
  (cd "$TMP" && "$BIN" "${args[@]}" --stats s.json --patches-csv p.csv --shots-csv sh.csv --residual-plot r.png > log 2>&1) \
    || { cat "$TMP/log" >&2; exit 1; }
  python3 - "$TMP/s.json" "$res" "host-sim ${args[*]}" >> "$OUT" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
p = s.get("proxels")
r = s.get("reference")
k = max(s["shots"], 1)
ups = {u["update"]: u["cycles_per_shot"] for u in p["updates"]} if p else {}
counted = ups[p["update"]] if p else s["reduce_cycles_per_shot"]
row = [s["scene"], s["n"], s["patches"], p["shots_by"] if p else "beams", p["resolution"] if p else "",
       sys.argv[2], s["shots"], f"{s['residual']:.4f}", f"{s['cycles'] / k:.0f}", f"{s['messages_per_shot']:.0f}", s["cycles"],
       f"{p['select_cycles_per_shot']:.0f}" if p else "", f"{p['projection_cycles_per_shot']:.0f}" if p else f"{s['diffusion_cycles_per_shot']:.0f}",
       f"{counted:.0f}", f"{p['triangles_per_shot']:.0f}" if p else "",
       p["bytes_per_cell"] if p else s["bytes_per_cell_added"] + s["bytes_per_light_cell"],
       f"{p['zone_yield']:.4f}" if p else "", f"{p['rect_yield']:.4f}" if p else "",
       f"{r['rms_relative_error']:.4f}" if r else "", f"{s['wall_seconds']:.1f}"]
row += [f"{ups[u]:.0f}" if p else "" for u in ["xnet-proxels", "xnet-modulo", "xnet-facets", "router-proxels", "router-modulo", "reduce"]]
print(",".join(str(v) for v in row) + ',"' + sys.argv[3] + '"')
PY
}
for row in $ROWS; do
  IFS=: read -r scene n res ref <<< "$row"
  for m in $METHODS; do run "$scene" "$n" "$m" "$res" "$ref"; done
done
. "$(dirname "$0")/lib.sh"
(cd "$(dirname "$0")/.." && bench_header "ROWS=\"$ROWS\" METHODS=\"$METHODS\" THREADS=$THREADS bash bench/proxel_shots.sh $1") > "${OUT%.csv}.md"
echo "* the runs took $((SECONDS / 60)) min $((SECONDS % 60)) s in all (one after another)" >> "${OUT%.csv}.md"
echo >> "${OUT%.csv}.md"
python3 - "$OUT" >> "${OUT%.csv}.md" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
def n(v): return f"{int(float(v)):,}".replace(",", " ") if v else "—"
print("Same patches, same residual; cycles count the update `reduce` (rc2's merge to cell (0, 0)).")
print()
print("| scene | n | patches | shots by | R | shots | residual | cycles / shot | of which projection | update | messages / shot | bytes / cell | yield (zones / rectangles) | RMS vs reference | wall s |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    y = f"{r['zone_yield']} / {r['rect_yield']}" if r["zone_yield"] else "—"
    print(f"| {r['scene']} | {r['n']} | {n(r['patches'])} | {r['shots_by']} | {r['resolution'] or '—'} | {n(r['shots'])} | {r['residual']} | "
          f"{n(r['cycles_per_shot'])} | {n(r['projection_cycles_per_shot'])} | {n(r['update_cycles_per_shot'])} | {n(r['messages_per_shot'])} | "
          f"{n(r['bytes_per_cell'])} | {y} | {r['rms_vs_reference'] or '—'} | {r['wall_seconds']} |")
print()
print("Update strategies (§6.2.6), cycles per shot, from the same depth buffers:")
print()
ups = ["xnet_proxels", "xnet_modulo", "xnet_facets", "router_proxels", "router_modulo", "reduce"]
print("| scene | n | shots by | R | " + " | ".join(u.replace("_", "-") for u in ups) + " | modulo gain: xnet / router |")
print("|---|---|---|---|" + "---|" * len(ups) + "---|")
for r in [r for r in rows if r["shots_by"] != "beams"]:
    g = lambda a, b: f"{float(r['update_' + a]) / max(float(r['update_' + b]), 1):.1f}"
    print(f"| {r['scene']} | {r['n']} | {r['shots_by']} | {r['resolution']} | " + " | ".join(n(r['update_' + u]) for u in ups)
          + f" | {g('xnet_proxels', 'xnet_modulo')} / {g('router_proxels', 'router_modulo')} |")
print()
print("```text")
for r in rows:
    print(r["command"])
print("```")
PY
cat "${OUT%.csv}.md"
