#!/usr/bin/env bash
# How much more work the Cornell box costs through its camera than in the fitted view, and how
# much of it the hidden-voxel skip could still drop with finer blocks: beams, cycles and skipped
# rays of `host-sim render --view scene|fitted --frustum-blocks 8|32` at several n. With 32
# blocks at n = 32 each block is one column wide, so the skip drops every beam whose frustum
# meets no visible voxel (the exact test, see cell_core::occupancy): what is left, every pixel
# may need.
#
# Usage: bench/camera_surplus.sh BIN     (env NS="32 64 128", OUT=bench-out/camera_surplus.csv;
#                                          the markdown table goes to ${OUT%.csv}.md)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/camera_surplus.sh BIN" >&2; exit 2; }
BIN=$(realpath -e "$1")
NS=${NS:-"32 64 128"}
OUT=${OUT:-bench-out/camera_surplus.csv}
REV=$(git -C "$(dirname "$0")" rev-parse --short HEAD 2>/dev/null || echo unknown)
mkdir -p "$(dirname "$OUT")"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "n,view,blocks,beams,cycles,rays_skipped" > "$OUT"
for n in $NS; do
  for view in scene fitted; do
    for b in 8 32; do
      "$BIN" render --n "$n" --view "$view" --frustum-blocks "$b" --quiet --out "$TMP/o.png" --stats "$TMP/s.json" 2>"$TMP/log" \
        || { cat "$TMP/log" >&2; exit 1; }
      python3 -c '
import json, sys
l = json.load(open(sys.argv[1]))["light"]
print(",".join(sys.argv[2:] + [str(l[k]) for k in ("beams_processed", "cycles", "rays_skipped")]))
' "$TMP/s.json" "$n" "$view" "$b" >> "$OUT"
    done
  done
done
python3 - "$OUT" "$REV" > "${OUT%.csv}.md" <<'PY'
import csv, datetime, sys
rows = list(csv.DictReader(open(sys.argv[1])))
at = {(r["n"], r["view"], r["blocks"]): r for r in rows}
print(f"`bash bench/camera_surplus.sh target/release/host-sim`, commit {sys.argv[2]}, "
      f"{datetime.date.today().isoformat()} (counts: exact, any machine):")
print()
print("| n | blocks | camera beams | fitted beams | camera / fitted | camera cycles | fitted cycles |")
print("|---|---|---|---|---|---|---|")
for n in dict.fromkeys(r["n"] for r in rows):
    for b in ("32", "8"):
        c, f = at[(n, "scene", b)], at[(n, "fitted", b)]
        g = lambda x: f"{int(x):,}".replace(",", " ")
        ratio = int(c["beams"]) / int(f["beams"])
        print(f"| {n} | {b} | {g(c['beams'])} | {g(f['beams'])} | {ratio:.2f}× | {g(c['cycles'])} | {g(f['cycles'])} |")
PY
cat "${OUT%.csv}.md"
