#!/usr/bin/env bash
# Sources over MPI ranks (docs/MPI.md): the plain binary, `mpirun -np 1` and `mpirun -np 2`
# (each rank with all cores' threads, then with one thread each) on a many-light scene.
# RUNS interleaved runs of each (default 3), the median wall time; every image compared byte
# for byte with the plain binary's. Needs Open MPI (openmpi-bin libopenmpi-dev libclang-dev).
#   SCENE=classe N=256 RUNS=3 bash bench/mpi_sources.sh   (SKIP_BUILD=1: reuse bench-out/mpi's binaries)
#   ROWS="plain np2t1free": only these rows (names below; plain always runs first, the
#   reference image)
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/lib.sh
SCENE=${SCENE:-classe}
N=${N:-256}
RUNS=${RUNS:-3}
OUT=bench-out/mpi
mkdir -p "$OUT"
mpi_binaries "$OUT"
ARGS="render $SCENE --n $N --quiet"
# Open MPI binds each rank to one core by default (np <= 2): a rank then sees one core and runs
# one thread. The --bind-to none rows let each rank's threads use every core.
names=("plain" "np1" "np1free" "np2" "np2t1" "np2t1free")
cmds=(
  "$OUT/host-sim-plain $ARGS"
  "mpirun -np 1 $OUT/host-sim-mpi $ARGS"
  "mpirun -np 1 --bind-to none $OUT/host-sim-mpi $ARGS"
  "mpirun --oversubscribe -np 2 $OUT/host-sim-mpi $ARGS"
  "mpirun --oversubscribe -np 2 $OUT/host-sim-mpi --threads 1 $ARGS"
  "mpirun --oversubscribe -np 2 --bind-to none $OUT/host-sim-mpi --threads 1 $ARGS"
)
ASKED=${ROWS:-}
ROWS=${ROWS:-${names[*]}}
declare -A times
for run in $(seq "$RUNS"); do
  for i in "${!names[@]}"; do
    if [[ $i -gt 0 && " $ROWS " != *" ${names[$i]} "* ]]; then continue; fi
    t0=$(date +%s.%N)
    ${cmds[$i]} --out "$OUT/${names[$i]}.png" 2> "$OUT/${names[$i]}.log"
    t1=$(date +%s.%N)
    times[${names[$i]}]+="$(echo "$t1 - $t0" | bc) "
    cmp -s "$OUT/plain.png" "$OUT/${names[$i]}.png" || { echo "${names[$i]}: image differs from the plain binary's" >&2; exit 1; }
  done
done
bench_header "SCENE=$SCENE N=$N RUNS=$RUNS${ASKED:+ ROWS=\"$ASKED\"} bash bench/mpi_sources.sh"
lights=$(grep -o '[0-9]* light(s)' "$OUT/plain.log" | head -1)
echo "* scene: $SCENE at n = $N, $lights; every image byte-identical to the plain binary's"
echo
echo "| command | wall s (runs) | median s | vs plain |"
echo "|---|---|---|---|"
plain_median=$(echo "${times[plain]}" | tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
for i in "${!names[@]}"; do
  if [[ -z ${times[${names[$i]}]:-} ]]; then continue; fi
  ts=$(echo "${times[${names[$i]}]}" | tr ' ' '\n' | grep . | sort -g)
  median=$(echo "$ts" | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
  list=$(echo "${times[${names[$i]}]}" | awk '{for (i = 1; i <= NF; i++) printf "%s%.1f", (i > 1 ? ", " : ""), $i}')
  shown=${cmds[$i]//$OUT\//}
  printf '| `%s` | %s | %.1f | %.2f× |\n' "$shown" "$list" "$median" "$(echo "$plain_median / $median" | bc -l)"
done
