#!/usr/bin/env bash
# Memory per rank of a grid cut into tiles (docs/MPI.md, `--spread tiles`): one process
# (`mpirun -np 1`) against K ranks of one thread each, Cornell through its camera at each N.
# A rank's peak RSS is /usr/bin/time's for a run that ends, else its VmHWM when the run is
# stopped, SECS seconds after its start (default 60: long enough at n = 1 024 for the lighting cells, which are allocated
# when the light phase starts, to be held; the peak then is the run's but for the cycle loop's
# growing lists) or ends by itself, whichever comes first; the time says which. From the
# one- and K-rank peaks, the bytes a cell every rank holds whole (W) and those a rank holds for
# its band only (B): peak(K) = (W + B / K) · n². Needs Open MPI.
#   NS="512 1024" RANKS="2" SECS=60 bash bench/mpi_memory.sh   (SKIP_BUILD=1: reuse bench-out/mpi's binaries)
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/lib.sh
NS=${NS:-512 1024}
RANKS=${RANKS:-2}
SECS=${SECS:-60}
OUT=bench-out/mpi
mkdir -p "$OUT"
mpi_binaries "$OUT"
cat > "$OUT/timed.sh" <<'SH'
#!/bin/sh
exec /usr/bin/time -f %M -o "$RSS_DIR/rss.${OMPI_COMM_WORLD_RANK:-0}" "$@"
SH
chmod +x "$OUT/timed.sh"
export RSS_DIR="$OUT/rss-memory"
mkdir -p "$RSS_DIR"
csv="$OUT/mpi_memory.csv"
echo "scene,n,ranks,stopped_after_s,ended,rss_mib_per_rank" > "$csv"
for N in $NS; do
  for K in 1 $RANKS; do
    rm -f "$RSS_DIR"/rss.*
    log="$OUT/memory-$N-np$K.log"
    t0=$(date +%s)
    mpirun -np "$K" --bind-to none "$OUT/timed.sh" "$OUT/host-sim-mpi" --threads 1 --spread tiles \
      render --n "$N" --quiet --out "$OUT/memory-$N-np$K.png" > "$log" 2>&1 &
    launcher=$!
    while kill -0 "$launcher" 2> /dev/null && (($(date +%s) - t0 < SECS)); do sleep 1; done
    if kill -0 "$launcher" 2> /dev/null; then
      ended=no
      # Each rank's peak so far (VmHWM, KiB), in rank order, then the run stopped.
      rss=$(for pid in $(pgrep -x host-sim-mpi); do
        echo "$(tr '\0' '\n' < "/proc/$pid/environ" | sed -n 's/^OMPI_COMM_WORLD_RANK=//p') $(awk '/VmHWM/ {print $2}' "/proc/$pid/status")"
      done | sort -n | awk '{printf "%s%.0f", (NR > 1 ? "/" : ""), $2 / 1024}')
      pkill -KILL -x host-sim-mpi || true
      wait "$launcher" || true
    else
      ended=yes
      wait "$launcher" || true
      rss=$(cat "$RSS_DIR"/rss.* | awk '{printf "%s%.0f", (NR > 1 ? "/" : ""), $1 / 1024}')
    fi
    echo "cornell,$N,$K,$(($(date +%s) - t0)),$ended,$rss" >> "$csv"
  done
done
bench_header "NS=\"$NS\" RANKS=\"$RANKS\" SECS=$SECS bash bench/mpi_memory.sh"
python3 - "$csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print()
print("| n | ranks | run | peak RSS MiB per rank | largest rank / one process | W: whole on every rank, B a cell | B: the band's, B a cell |")
print("|---|---|---|---|---|---|---|")
one = {}
for r in rows:
    n, k = int(r["n"]), int(r["ranks"])
    peaks = [float(x) for x in r["rss_mib_per_rank"].split("/")]
    run = "whole" if r["ended"] == "yes" else f"stopped after {r['stopped_after_s']} s"
    if k == 1:
        one[n] = peaks[0]
        print(f"| {n} | 1 | {run} | {peaks[0]:.0f} | 1.00 | — | — |")
        continue
    m1, mk = one[n], max(peaks)
    # m1 = (W + B) n², mk = (W + B / k) n²
    b = (m1 - mk) / (1 - 1 / k) * 2**20 / n**2
    w = m1 * 2**20 / n**2 - b
    print(f"| {n} | {k} | {run} | {'/'.join(f'{p:.0f}' for p in peaks)} | {mk / m1:.2f} | {w:.0f} | {b:.0f} |")
PY
