#!/usr/bin/env bash
# One criterion bench target's medians as BENCHMARKS.md's tables, with the command, commit,
# machine, date and the machine's load (criterion's times are wall-clock: on a shared machine
# compare rows only within one run).
#
# Usage: bench/criterion.sh PKG BENCH [CRITERION ARGS ...]
#   runs `cargo bench -p PKG --bench BENCH -- CRITERION ARGS` (sample sizes and measurement
#   times are the bench's own unless the args set them), then writes bench-out/criterion-BENCH.md
#   (TAG=T: bench-out/criterion-BENCH-T.md): one `bench/criterion_table.py` table of what this
#   run measured per entry of TABLES (';'-separated prefix lists, a leading "pivot:" for a
#   GROUP/FUNCTION/INPUT pivot; default: one table of everything).
# BENCHMARKS.md's tables:
#   bash bench/criterion.sh host-sim grid
#   bash bench/criterion.sh host-sim reference
#   TABLES="voxelize dexel_insert beam_split fifo_accept light_step shade_pixel;pivot:skips;occluders" \
#     bash bench/criterion.sh cell-core cell --warm-up-time 1 --measurement-time 2
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 2 ] || { echo "usage: bench/criterion.sh PKG BENCH [CRITERION ARGS ...]" >&2; exit 2; }
PKG=$1 BENCH=$2
shift 2
TABLES=${TABLES:-""}
mkdir -p bench-out
MD=bench-out/criterion-$BENCH${TAG:+-$TAG}.md
# Build first, so the marker and the load figures are the measurement's own.
cargo bench -q -p "$PKG" --bench "$BENCH" --no-run
MARK=$(mktemp)
trap 'rm -f "$MARK"' EXIT
sleep 1
load0=$(cut -d' ' -f1-3 /proc/loadavg)
t0=$(date +%s)
cargo bench -q -p "$PKG" --bench "$BENCH" -- "$@" > "bench-out/criterion-$BENCH${TAG:+-$TAG}.log"
t1=$(date +%s)
load1=$(cut -d' ' -f1-3 /proc/loadavg)
. bench/lib.sh
cmd="cargo bench -p $PKG --bench $BENCH${*:+ -- $*}"
{
  bench_header "${TABLES:+TABLES=\"$TABLES\" }bash bench/criterion.sh $PKG $BENCH${*:+ $*}  ($cmd, then bench/criterion_table.py)"
  echo "* load average (1, 5, 15 min) before / after: $load0 / $load1; $((t1 - t0)) s"
  IFS=';' read -ra sets <<< "${TABLES:-}"
  [ ${#sets[@]} -gt 0 ] || sets=("")
  for s in "${sets[@]}"; do
    echo
    if [[ $s == pivot:* ]]; then
      # shellcheck disable=SC2086
      python3 bench/criterion_table.py --since "$MARK" --pivot ${s#pivot:}
    else
      # shellcheck disable=SC2086
      python3 bench/criterion_table.py --since "$MARK" $s
    fi
  done
} | tee "$MD"
