#!/usr/bin/env bash
# Where the host's time goes: one build of host-sim on a fixed suite, the light phase's wall
# time split by phase of the cycle loop (stats light.phase_seconds), with 1 and 2 threads, and
# (cachegrind) its instructions split by concern — the cell's own work (frustum test, exact
# occluders, beam split, fate and routing, step and buffers) against the engine's.
#
# Usage: bench/host_phases.sh BIN
#   e.g. REPS=3 bench/host_phases.sh target/release/host-sim
#
# Rows: the Cornell box through its camera at n = 128 and 256, teapot-floor and bureau1 at 256
# (ROWS picks among the render rows of bench/host_suite.sh without --threads). Every run is
# the row's command with `--threads T --quiet --out … --stats …`; the table gives medians
# over REPS runs per (row, threads), threads 1 and 2 interleaved, and the 2-thread speed-up of
# each phase (ratio of medians).
#
# Environment:
#   REPS=3         runs of each (row, threads)
#   ROWS="…"       rows to run (default: all four)
#   CACHEGRIND=1   0: no instruction split (cachegrind of `render --n 128 --threads 1`, ~40 s)
#   OUT=bench-out/host_phases.csv  one line per run; the markdown tables go to ${OUT%.csv}.md
#   REV            the commit the binary was built from, for the header (default: git HEAD)
#
# CSV columns: row, threads, rep, light_s (stats light.wall_seconds), beams, then one column per
# phase in seconds: setup, emit, step, gather, links, pop, next, tally (see PhaseSeconds in
# host-sim/src/machine/lighting/diffuse/mod.rs: step and links run in parallel, the others serially).
set -euo pipefail

die() { echo "host_phases: $*" >&2; exit 1; }
[ $# -eq 1 ] || die "usage: bench/host_phases.sh BIN (see the header of this script)"
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=$(realpath -e "$1") || die "no such file: $1"
REPS=${REPS:-3}
ROWS=${ROWS:-"cornell-128 cornell-256 teapot-256 bureau1-256"}
CACHEGRIND=${CACHEGRIND:-1}
OUT=${OUT:-bench-out/host_phases.csv}
REV=${REV:-$(git -C "$HERE" rev-parse --short HEAD 2>/dev/null || echo unknown)}
mkdir -p "$(dirname "$OUT")"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

# shellcheck source=bench/host_suite.sh
source "$HERE/host_suite.sh"
for row in $ROWS; do
  [ -n "${ARGS[$row]:-}" ] && [[ ${ARGS[$row]} == render* ]] && [[ ${ARGS[$row]} != *--threads* ]] \
    || die "row '$row' is not a render row without --threads (rows: $ALL_ROWS)"
done

PHASES="setup emit step gather links pop next tally"
echo "row,threads,rep,light_s,beams,${PHASES// /,}" > "$OUT"
for row in $ROWS; do
  for rep in $(seq 1 "$REPS"); do
    for t in 1 2; do
      # shellcheck disable=SC2086
      "$BIN" ${ARGS[$row]} --threads "$t" --quiet --out "$TMP/out.png" --stats "$TMP/s.json" 2>"$TMP/err" \
        || { cat "$TMP/err" >&2; die "$row --threads $t failed"; }
      python3 - "$TMP/s.json" "$row" "$t" "$rep" "$PHASES" >> "$OUT" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))["light"]
p = s["phase_seconds"]
cols = [sys.argv[2], sys.argv[3], sys.argv[4], f'{s["wall_seconds"]:.4f}', str(s["beams_processed"])]
print(",".join(cols + [f"{p[k]:.4f}" for k in sys.argv[5].split()]))
PY
      tail -1 "$OUT" | sed 's/^/  /' >&2
    done
  done
done

CG=""
if [ "$CACHEGRIND" = 1 ]; then
  command -v valgrind >/dev/null || die "CACHEGRIND=1 needs valgrind (apt-get install valgrind)"
  valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file="$TMP/cg.out" \
    "$BIN" render --n 128 --threads 1 --quiet --out "$TMP/cg.png" --stats "$TMP/cg.json" 2>"$TMP/cg.err" \
    || { tail "$TMP/cg.err" >&2; die "cachegrind run failed"; }
  cg_annotate --auto=no --threshold=0 "$TMP/cg.out" > "$TMP/cg.txt" 2>/dev/null
  CG="$TMP/cg.txt"
fi

python3 "$HERE/host_phases_table.py" "$OUT" "$CG" "$TMP/cg.json" \
  "bench/host_phases.sh $1 (REPS=$REPS)" "$REV" > "${OUT%.csv}.md"
cat "${OUT%.csv}.md"
