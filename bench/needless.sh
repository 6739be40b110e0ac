#!/usr/bin/env bash
# How much of a render's diffusion no pixel needs (issue 50 item 4): every row renders one scene
# three times, `--oracle-skip off|voxels|rays` (the host drops the beams that carry no pixel's
# target ray to a later layer, or whose voxel is on none before its target: a measurement, not a
# cell's rule), checks that the three PNGs are byte-identical, and reports beams, messages,
# cycles and light seconds of each.
#
# Usage: bench/needless.sh BIN
#   env ROWS="cornell:128 cornell-fitted:128 …" (SCENE[-fitted]:N; default below),
#       OUT=bench-out/needless.csv (the markdown table goes to ${OUT%.csv}.md)
# CSV columns: scene, view, n, oracle (off|voxels|rays), beams, messages, cycles, light_s.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=bench/lib.sh
. "$HERE/lib.sh"
[ $# -eq 1 ] || { echo "usage: bench/needless.sh BIN" >&2; exit 2; }
BIN=$(realpath -e "$1")
ROWS=${ROWS:-"cornell:64 cornell:128 cornell:256 cornell-fitted:128 cornell-fitted:256 teapot-floor:128 teapot-floor:256 bureau1:128 bureau1:256 bureau2:128"}
OUT=${OUT:-bench-out/needless.csv}
mkdir -p "$(dirname "$OUT")"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "scene,view,n,oracle,beams,messages,cycles,light_s" > "$OUT"
for row in $ROWS; do
  spec=${row%%:*}
  n=${row##*:}
  scene=${spec%-fitted}
  view=auto
  [ "$spec" != "$scene" ] && view=fitted
  for o in off voxels rays; do
    "$BIN" render "$scene" --n "$n" --view "$view" --oracle-skip "$o" --quiet \
      --out "$TMP/$o.png" --stats "$TMP/$o.json" 2>"$TMP/log" || { cat "$TMP/log" >&2; exit 1; }
    python3 -c '
import json, sys
s = json.load(open(sys.argv[1]))
l, view = s["light"], ("camera" if str(s.get("view", "")).startswith("camera") else "fitted")
print(",".join([sys.argv[2], view] + sys.argv[3:] + [str(l[k]) for k in ("beams_processed", "messages", "cycles")] + ["%.3f" % l["wall_seconds"]]))
' "$TMP/$o.json" "$scene" "$n" "$o" >> "$OUT"
  done
  for o in voxels rays; do
    cmp -s "$TMP/off.png" "$TMP/$o.png" || { echo "needless: $row: --oracle-skip $o changed the image" >&2; exit 1; }
  done
done
{
  bench_header "ROWS=\"$ROWS\" bash bench/needless.sh target/release/host-sim"
  echo
  python3 - "$OUT" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
at = {(r["scene"], r["view"], r["n"], r["oracle"]): r for r in rows}
g = lambda x: f"{int(x):,}".replace(",", " ")
print("| scene | view | n | beams | needed: on target voxels | needed: carrying target rays | cycles off / voxels / rays | light s off / rays |")
print("|---|---|---|---|---|---|---|---|")
for key in dict.fromkeys((r["scene"], r["view"], r["n"]) for r in rows):
    off, vox, ray = (at[key + (o,)] for o in ("off", "voxels", "rays"))
    b = int(off["beams"])
    pct = lambda r: f"{g(r['beams'])} ({100 * int(r['beams']) / b:.0f} %)"
    view = key[1]
    print(f"| {key[0]} | {view} | {key[2]} | {g(b)} | {pct(vox)} | {pct(ray)} | "
          f"{g(off['cycles'])} / {g(vox['cycles'])} / {g(ray['cycles'])} | {off['light_s']} / {ray['light_s']} |")
PY
  echo
  echo "Images byte-identical under all three in every row (the script fails otherwise). Counts are exact (any machine); seconds are this machine's, one run each."
} > "${OUT%.csv}.md"
cat "${OUT%.csv}.md"
