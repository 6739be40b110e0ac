#!/usr/bin/env bash
# The update of proxel shots (radiosity thesis §6.2.6) against the thesis's own figures: every
# strategy's cycles and messages per shot on bureau2 with the projection disk, the "modulo"
# gains (thesis: ≈ 20 at R = 256, ≈ 34 at R = 1024, 16 K PEs = n 128, global router), and the
# router's mean simultaneous transfers per routing cycle without modulo (thesis: 2.16 at
# R = 512, 1.75 at R = 1024, of 64 possible on 1 024 PEs = n 32 in groups of 16).
#
# Usage: bench/proxel_router.sh BIN   (env ROWS="scene:n:R:shots ..."; THREADS=2;
#        OUT=bench-out/proxel_router.csv, markdown in ${OUT%.csv}.md)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/proxel_router.sh BIN" >&2; exit 2; }
BIN=$(realpath -e "$1")
ROWS=${ROWS:-"bureau2:32:256:20 bureau2:32:512:20 bureau2:128:256:20 bureau2:128:512:20 bureau2:128:1024:20"}
THREADS=${THREADS:-2}
OUT=${OUT:-bench-out/proxel_router.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "scene,n,resolution,shots,groups,update,cycles_per_shot,messages_per_shot,command" > "$OUT"
for row in $ROWS; do
  IFS=: read -r scene n r shots <<< "$row"
  args=(radiosity "$scene" --n "$n" --shots-by proxels-disk --resolution "$r" --shots "$shots" --residual 0 --threads "$THREADS" --quiet)
  (cd "$TMP" && "$BIN" "${args[@]}" --stats s.json --patches-csv p.csv --residual-plot r.png > log 2>&1) \
    || { cat "$TMP/log" >&2; exit 1; }
  python3 - "$TMP/s.json" "host-sim ${args[*]}" >> "$OUT" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
p = s["proxels"]
groups = p["router_groups"]
for u in p["updates"]:
    print(f'{s["scene"]},{s["n"]},{p["resolution"]},{s["shots"]},{groups},{u["update"]},'
          f'{u["cycles_per_shot"]:.1f},{u["messages_per_shot"]:.1f},"{sys.argv[2]}"')
PY
done
. "$(dirname "$0")/lib.sh"
(cd "$(dirname "$0")/.." && bench_header "ROWS=\"$ROWS\" THREADS=$THREADS bash bench/proxel_router.sh $1") > "${OUT%.csv}.md"
echo >> "${OUT%.csv}.md"
python3 - "$OUT" >> "${OUT%.csv}.md" <<'PY'
import csv, sys
from collections import OrderedDict
rows = list(csv.DictReader(open(sys.argv[1])))
runs = OrderedDict()
for r in rows:
    runs.setdefault((r["scene"], r["n"], r["resolution"]), {})[r["update"]] = r
    runs[(r["scene"], r["n"], r["resolution"])]["_"] = r
ups = ["xnet-proxels", "xnet-modulo", "xnet-facets", "router-proxels", "router-modulo", "reduce"]
def n(v): return f"{float(v):,.0f}".replace(",", " ")
thesis_gain = {"256": "≈ 20", "1024": "≈ 34"}
thesis_sim = {"512": "2.16", "1024": "1.75"}
print("Cycles per shot of each update strategy (mean over the shots), from the same depth buffers:")
print()
print("| scene | n (cells) | R | shots | " + " | ".join(ups) + " |")
print("|---|---|---|---|" + "---|" * len(ups))
for (sc, nn, r), u in runs.items():
    print(f"| {sc} | {nn} ({int(nn)**2:,}) | {r} | {u['_']['shots']} | ".replace(",", " ") + " | ".join(n(u[x]["cycles_per_shot"]) for x in ups) + " |")
print()
print("The thesis's figures beside ours (router: groups of 4 × 4 cells, one message in and one out per group per cycle):")
print()
print("| n (cells, groups) | R | modulo gain, router: ours | thesis (16 K PEs) | modulo gain, xnet: ours | router transfers per cycle without modulo: ours (of groups) | thesis (1 024 PEs, of 64) |")
print("|---|---|---|---|---|---|---|")
for (sc, nn, r), u in runs.items():
    rp, rm = u["router-proxels"], u["router-modulo"]
    xp, xm = u["xnet-proxels"], u["xnet-modulo"]
    g = int(u["_"]["groups"])
    gain = float(rp["cycles_per_shot"]) / max(float(rm["cycles_per_shot"]), 1e-9)
    xgain = float(xp["cycles_per_shot"]) / max(float(xm["cycles_per_shot"]), 1e-9)
    sim = float(rp["messages_per_shot"]) / max(float(rp["cycles_per_shot"]), 1e-9)
    th_g = thesis_gain.get(r, "—") if nn == "128" else "—"
    th_s = thesis_sim.get(r, "—") if nn == "32" else "—"
    print(f"| {nn} ({int(nn)**2}, {g}) | {r} | {gain:.1f} | {th_g} | {xgain:.1f} | {sim:.2f} (of {g}) | {th_s} |")
print()
print("```text")
for k, u in runs.items():
    print(u["_"]["command"])
print("```")
PY
cat "${OUT%.csv}.md"
