#!/usr/bin/env bash
# The grid cut into tiles over MPI ranks (docs/MPI.md, `--spread tiles`): the plain binary
# (all cores, then one thread), `mpirun -np 1` and `mpirun -np 2` (one thread a rank), each run
# wrapped in /usr/bin/time per rank for its peak RSS; rank 0's account gives each rank's bytes
# across its tile's edges per cycle, its seconds in the seam and its band's share of the beams. RUNS interleaved runs of each row (default 3), medians;
# every image compared byte for byte with the plain binary's. Needs Open MPI.
#   SCENE=cornell NS="256 512" RUNS=3 bash bench/mpi_tiles.sh   (SKIP_BUILD=1: reuse bench-out/mpi's binaries)
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/lib.sh
SCENE=${SCENE:-cornell}
NS=${NS:-256 512}
RUNS=${RUNS:-3}
OUT=bench-out/mpi
mkdir -p "$OUT"
mpi_binaries "$OUT"
# Each process's peak RSS into a file of its own (the ranks' outputs interleave).
cat > "$OUT/timed.sh" <<'SH'
#!/bin/sh
exec /usr/bin/time -f %M -o "$RSS_DIR/rss.${OMPI_COMM_WORLD_RANK:-0}" "$@"
SH
chmod +x "$OUT/timed.sh"
export RSS_DIR="$OUT/rss"
mkdir -p "$RSS_DIR"
TIME="$OUT/timed.sh"
names=("plain" "plain-t1" "np1" "np2")
csv="$OUT/mpi_tiles.csv"
echo "scene,n,row,run,wall_s,light_s,rss_mib_per_rank,edge_bytes_per_cycle_per_rank,seam_s_per_rank,beam_share_per_rank" > "$csv"
for N in $NS; do
  ARGS="render $SCENE --n $N"
  cmds=(
    "$TIME $OUT/host-sim-plain $ARGS"
    "$TIME $OUT/host-sim-plain --threads 1 $ARGS"
    "mpirun -np 1 --bind-to none $TIME $OUT/host-sim-mpi --spread tiles $ARGS"
    "mpirun -np 2 --bind-to none $TIME $OUT/host-sim-mpi --threads 1 --spread tiles $ARGS"
  )
  for run in $(seq "$RUNS"); do
    for i in "${!names[@]}"; do
      log="$OUT/tiles-$N-${names[$i]}.log"
      rm -f "$RSS_DIR"/rss.*
      t0=$(date +%s.%N)
      ${cmds[$i]} --out "$OUT/tiles-$N-${names[$i]}.png" > "$log" 2>&1
      t1=$(date +%s.%N)
      cmp -s "$OUT/tiles-$N-plain.png" "$OUT/tiles-$N-${names[$i]}.png" || { echo "$N ${names[$i]}: image differs from the plain binary's" >&2; exit 1; }
      light=$(grep -o 'light [0-9.]*,' "$log" | tail -1 | tr -dc '0-9.')
      rss=$(cat "$RSS_DIR"/rss.* | awk '{printf "%s%.0f", (NR > 1 ? "/" : ""), $1 / 1024}')
      # rank 0's account of a tiled run: per rank, edge bytes a cycle, seconds in the seam, beam share
      acct=$(grep 'ranks: by rank' "$log" || true)
      edge=$(echo "$acct" | sed -n 's/.*a cycle: \([^;]*\);.*/\1/p' | tr -d ' ' | tr ',' '/')
      seam=$(echo "$acct" | sed -n 's/.*waiting): \([^;]*\);.*/\1/p' | tr -d ' ' | tr ',' '/')
      share=$(echo "$acct" | sed -n 's/.*processed: \(.*\)$/\1/p' | tr -d ' %' | tr ',' '/')
      echo "$SCENE,$N,${names[$i]},$run,$(echo "$t1 - $t0" | bc),$light,$rss,$edge,$seam,$share" >> "$csv"
    done
  done
done
bench_header "SCENE=$SCENE NS=\"$NS\" RUNS=$RUNS bash bench/mpi_tiles.sh"
python3 - "$csv" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
shown = {"plain": "plain binary, 2 threads", "plain-t1": "plain binary, `--threads 1`",
         "np1": "`mpirun -np 1 --bind-to none … --spread tiles`", "np2": "`mpirun -np 2 --bind-to none … --threads 1 --spread tiles`"}
print("| scene | n | command | runs | wall s (median) | light s (median) | vs plain, 1 thread | peak RSS MiB per rank | edge bytes a cycle per rank | s in the seam per rank | share of the beams per rank, % |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for n in dict.fromkeys(r["n"] for r in rows):
    base = statistics.median(float(r["wall_s"]) for r in rows if r["n"] == n and r["row"] == "plain-t1")
    for key in shown:
        rs = [r for r in rows if r["n"] == n and r["row"] == key]
        wall = statistics.median(float(r["wall_s"]) for r in rs)
        light = statistics.median(float(r["light_s"]) for r in rs)
        last = rs[-1]
        dash = lambda k: last[k] or "—"
        print(f"| {last['scene']} | {n} | {shown[key]} | {len(rs)} | {wall:.2f} | {light:.2f} | {base / wall:.2f}× | {last['rss_mib_per_rank']} | {dash('edge_bytes_per_cycle_per_rank')} | {dash('seam_s_per_rank')} | {dash('beam_share_per_rank')} |")
PY
