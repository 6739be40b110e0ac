#!/usr/bin/env bash
# The radiosity thesis's Tables 3.2 and 3.3 (§3.4.2): form factors from every vertex of a scene
# to its brightest source, by Wallace's rays (1, 4 × 4, 5 × 5 per vertex) and by the subdivided
# beam, timed on one thread; the beam's time by phase; each estimate's error against 32 × 32
# jittered rays per vertex. Only ratios carry (the thesis's machine is not this one).
#
# Usage: bench/ray_traced.sh BIN   (env SCENES="cornell bureau1 bureau2", LEVEL=4,
#                                   OUT=bench-out/ray_traced.csv; the table goes to ${OUT%.csv}.md)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/ray_traced.sh BIN" >&2; exit 2; }
BIN=$(realpath "$1")
SCENES=${SCENES:-cornell bureau1 bureau2}
LEVEL=${LEVEL:-4}
OUT=${OUT:-bench-out/ray_traced.csv}
mkdir -p "$(dirname "$OUT")"
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
MD=${OUT%.csv}.md
table=$("$BIN" form-factors --ray-traced "${SCENES// /,}" --ray-traced-level "$LEVEL" --ray-traced-csv "$OUT")
{
  echo "\`SCENES=\"$SCENES\" LEVEL=$LEVEL bash bench/ray_traced.sh BIN\` ($("$BIN" --version), commit $(git -C "$REPO" rev-parse --short HEAD)$(git -C "$REPO" diff --quiet HEAD || echo " + uncommitted changes")), $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'):"
  echo
  echo "$table"
} > "$MD"
cat "$MD"
