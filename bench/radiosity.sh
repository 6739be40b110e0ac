#!/usr/bin/env bash
# Progressive radiosity on the grid against the f64 reference (same patches, same shots):
# `host-sim radiosity cornell --reference` at a fixed number of shots and to the default 1 %
# residual, one row each, with the machine's cost per shot and its per-patch RMS error (and
# direct light's alone) against the reference.
#
# Usage: bench/radiosity.sh BIN    (env ROWS="64:12:60 64:12:-" — n:patch-size:shots, "-" for
#                                    the default stopping rule; THREADS=2;
#                                    OUT=bench-out/radiosity.csv, markdown in ${OUT%.csv}.md)
# The n = 128 rows of BENCHMARKS: ROWS="128:23:250 128:23:-" (4–16 CPU-minutes each).
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/radiosity.sh BIN" >&2; exit 2; }
BIN=$(realpath -e "$1")
ROWS=${ROWS:-"64:12:60 64:12:-"}
THREADS=${THREADS:-2}
OUT=${OUT:-bench-out/radiosity.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "scene,n,patch_size,patches,shots,residual,reference_shots,diffusion_cycles_per_shot,reduce_cycles_per_shot,messages_per_shot,bytes_per_cell_added,rms_machine,rms_direct_only,wall_seconds,command" > "$OUT"
for row in $ROWS; do
  IFS=: read -r n size shots <<< "$row"
  args=(radiosity cornell --n "$n" --patch-size "$size" --reference --threads "$THREADS" --quiet)
  [ "$shots" != "-" ] && args+=(--shots "$shots")
  # In the scratch directory: the job writes its default outputs (SCENE_patches.csv, ...) there.
  (cd "$TMP" && "$BIN" "${args[@]}" --stats s.json > log 2>&1) || { cat "$TMP/log" >&2; exit 1; }
  python3 - "$TMP/s.json" "$size" "host-sim ${args[*]} --stats s.json" >> "$OUT" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
r = s["reference"]
print(",".join(str(v) for v in [
    s["scene"], s["n"], sys.argv[2], s["patches"], s["shots"], f"{s['residual']:.4f}", r["shots"],
    f"{s['diffusion_cycles_per_shot']:.0f}", f"{s['reduce_cycles_per_shot']:.0f}", f"{s['messages_per_shot']:.0f}",
    s["bytes_per_cell_added"], f"{r['rms_relative_error']:.4f}", f"{r['direct_only_rms_relative_error']:.4f}",
    f"{s['wall_seconds']:.1f}", '"' + sys.argv[3] + '"']))
PY
done
. "$(dirname "$0")/lib.sh"
(cd "$(dirname "$0")/.." && bench_header "ROWS=\"$ROWS\" THREADS=$THREADS bash bench/radiosity.sh $1") > "${OUT%.csv}.md"
echo "* the runs took $((SECONDS / 60)) min $((SECONDS % 60)) s in all (one after another)" >> "${OUT%.csv}.md"
echo >> "${OUT%.csv}.md"
python3 - "$OUT" >> "${OUT%.csv}.md" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("```text")
for r in rows:
    print(r["command"])
print("```")
print()
print("| scene | n | patches | shots (reference's) | residual after | diffusion cycles / shot | reduction cycles / shot | "
      "messages / shot | bytes / cell added | per-patch RMS vs reference (machine / direct only) | wall s |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['scene']} | {r['n']} | {r['patches']} | {r['shots']} ({r['reference_shots']}) | {r['residual']} | "
          f"{r['diffusion_cycles_per_shot']} | {r['reduce_cycles_per_shot']} | {int(r['messages_per_shot']):,} | "
          f"{r['bytes_per_cell_added']} | {r['rms_machine']} / {r['rms_direct_only']} | {r['wall_seconds']} |".replace(",", " "))
PY
cat "${OUT%.csv}.md"
