#!/usr/bin/env bash
# Host cost of two builds of host-sim on a fixed suite: wall seconds, light seconds, core
# time per processed beam, peak RSS and (cachegrind) instructions per beam, base against new.
#
# Usage: bench/host_cost.sh BASE_BIN NEW_BIN
#   e.g. REPS=5 ROWS="cornell-128 cornell-128-t1" bench/host_cost.sh /tmp/host-sim-old target/release/host-sim
#
# The binaries are interleaved (for each row and repetition: base, then new), so the noise of
# the machine hits both alike; the summary takes medians. Every run writes its PNG/CSV and its
# --stats JSON into a temporary directory (nothing goes into the repository but the CSV and the
# markdown table). The script FAILS (exit 1) if base and new, or two repetitions, disagree on
# any simulated count of a row (the stats JSONs with every *wall*, *seconds* and peak_rss* key
# removed must be equal).
#
# Rows (ROWS picks among them, in this order):
#   cornell-128     render --n 128                 (the Cornell box through its camera)
#   cornell-128-t1  render --n 128 --threads 1     (core time per beam, single-threaded)
#   cornell-256     render --n 256
#   cornell-512     render --n 512                 (slow: ~165 s a run; SKIP="cornell-512")
#   teapot-256      render teapot-floor --n 256
#   bureau1-256     render bureau1 --n 256
#   bureau2-256     render bureau2 --n 256         (2 lights)
#   classe-128      render classe --n 128          (26 lights; columns dense with triangles)
#   classe-light-32 light classe --n 32            (every voxel's lit state: the full lit store)
#   radiosity-64    radiosity cornell --n 64 --residual 0.01
#
# Instructions: valgrind --tool=cachegrind --cache-sim=no (I refs of the whole process) with
# --threads 1, once per binary, on the rows of CG_ROWS (counts are deterministic to ~1e-4: two
# runs of one binary differ by that much). Radiosity n = 64 takes 381 s under cachegrind (149 G
# instructions), so its count is taken at n = 32 (same residual, ~20 s; 2 154 instructions per
# message against 1 923 at n = 64: compare base with new, not with n = 64); its stats have no
# beam count, so the table gives instructions and ns per simulated message for it.
#
# Environment:
#   REPS=3          timed repetitions of each row and binary
#   ROWS="…"        rows to run (default: all of the above); SKIP="…" rows to leave out
#   CACHEGRIND=1    0: no instruction counts
#   CG_ROWS="cornell-128 radiosity-64"  rows that get a cachegrind run
#   OUT=bench-out/host_cost.csv  the CSV (one line per run); the table goes to ${OUT%.csv}.md
#   BASE_REV, NEW_REV  the commits the binaries were built from, for the header (default: the
#                   git HEAD of the tree holding the binary, if any)
#   KEEP_TMP=1      keep the temporary directory (stats JSONs, logs, images)
#   NEW_KEYS=ignore a stats key that only one build writes (a field added between the two) is
#                   named on stderr and not compared (default: it fails the run like any
#                   difference); keys both write must still be equal
#
# CSV columns (blank where the job does not report the figure):
#   row, binary (base|new), rep (1..REPS; "cg" for the cachegrind run),
#   wall_s (measured around the process), light_s (render: stats light.wall_seconds;
#   radiosity, light: none), beams (render: light.beams_processed; light: beams_processed;
#   radiosity: none),
#   core_s (user + sys CPU s, /usr/bin/time), ns_per_beam (core_s × 1e9 / beams),
#   peak_rss_mib (/usr/bin/time %M), instr (cachegrind I refs), instr_per_beam,
#   cycles (simulated: render light.cycles, radiosity cycles), job_wall_s (the job's own
#   stats wall_seconds), messages (simulated link messages), ns_per_msg, instr_per_msg,
#   threads, user_s, sys_s, args (the host-sim command line, without the output options).
set -euo pipefail

die() { echo "host_cost: $*" >&2; exit 1; }

[ $# -eq 2 ] || die "usage: bench/host_cost.sh BASE_BIN NEW_BIN (see the header of this script)"
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/.." && pwd)
PY="$HERE/host_cost_table.py"
declare -A BIN
BIN[base]=$(realpath -e "$1") || die "no such file: $1"
BIN[new]=$(realpath -e "$2") || die "no such file: $2"
for b in base new; do [ -x "${BIN[$b]}" ] || die "$b binary ${BIN[$b]} is not executable"; done

# shellcheck source=bench/host_suite.sh
source "$HERE/host_suite.sh"
# The cachegrind command of a row: its own with --threads 1, unless given here.
declare -A CG_ARGS=(
  [radiosity-64]="radiosity cornell --n 32 --residual 0.01 --threads 1"
)

REPS=${REPS:-3}
ROWS=${ROWS:-$ALL_ROWS}
SKIP=${SKIP:-}
CACHEGRIND=${CACHEGRIND:-1}
CG_ROWS=${CG_ROWS:-"cornell-128 radiosity-64"}
OUT=${OUT:-$REPO/bench-out/host_cost.csv}
[[ "$REPS" =~ ^[1-9][0-9]*$ ]] || die "REPS must be a positive integer, not '$REPS'"
for r in $ROWS $SKIP $CG_ROWS; do [ -n "${ARGS[$r]:-}" ] || die "unknown row '$r' (rows: $ALL_ROWS)"; done
SELECTED=()
for r in $ALL_ROWS; do   # the suite's order, whatever the order of ROWS
  [[ " $ROWS " == *" $r "* && " $SKIP " != *" $r "* ]] && SELECTED+=("$r")
done
[ ${#SELECTED[@]} -gt 0 ] || die "no rows selected"
if [ "$CACHEGRIND" != 0 ] && ! command -v valgrind >/dev/null; then
  echo "host_cost: valgrind not found: no instruction counts" >&2
  CACHEGRIND=0
fi
[ -x /usr/bin/time ] || die "/usr/bin/time (GNU time) is needed"
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
MD=${OUT%.csv}.md

TMP=$(mktemp -d "${TMPDIR:-/tmp}/host_cost.XXXXXX")
if [ "${KEEP_TMP:-0}" = 1 ]; then echo "host_cost: temporary files in $TMP" >&2
else trap 'rm -rf "$TMP"' EXIT; fi
cd "$TMP"   # anything a job writes by default lands here, not in the repository

NPROC=$(nproc)

# The output options of a job (render: PNG; radiosity: two CSVs and a plot) under prefix $2.
out_args() {
  case $1 in
    render) echo "--quiet --out $2.png --stats $2.json" ;;
    light) echo "--quiet --lit-out $2.lit.csv --stats $2.json" ;;
    radiosity) echo "--quiet --patches-csv $2.patches.csv --shots-csv $2.shots.csv --residual-plot $2.residual.png --stats $2.json" ;;
    *) die "no output options known for job '$1'" ;;
  esac
}

threads_of() {   # the --threads of a command line, else host-sim's default (all cores)
  local a=($1) i
  for ((i = 0; i < ${#a[@]} - 1; i++)); do [ "${a[i]}" = --threads ] && { echo "${a[i+1]}"; return; }; done
  echo "$NPROC"
}

calc() { python3 -c "import sys; print(eval(sys.argv[1]))" "$1"; }

# Check a run's stats against the row's reference; exit on any difference.
check_same() {   # ref, other, what, what the ref is
  local diff
  if ! diff=$(python3 "$PY" same "$1" "$2"); then
    echo "host_cost: FAIL: $3 disagrees with $4 on simulated counts (reference != this run):" >&2
    echo "$diff" >&2
    exit 1
  fi
}

echo "row,binary,rep,wall_s,light_s,beams,core_s,ns_per_beam,peak_rss_mib,instr,instr_per_beam,cycles,job_wall_s,messages,ns_per_msg,instr_per_msg,threads,user_s,sys_s,args" > "$OUT"

# One timed run: appends its CSV line, checks its counts against the row's reference.
timed_run() {   # row, binary label, rep
  local row=$1 b=$2 rep=$3 args=${ARGS[$1]} tag="$1.$2.$3"
  local cmd=($args) t0 t1 wall user sys rss jw ls beams cycles msgs core nspb nspm
  read -ra outs <<< "$(out_args "${cmd[0]}" "$TMP/$tag")"
  t0=$(date +%s.%N)
  /usr/bin/time -o "$tag.time" -f "%U %S %M" "${BIN[$b]}" "${cmd[@]}" "${outs[@]}" > "$tag.log" 2>&1 \
    || { tail -20 "$tag.log" >&2; die "$b failed on '$args' (log above)"; }
  t1=$(date +%s.%N)
  wall=$(calc "round($t1 - $t0, 3)")
  read -r user sys rss < <(tail -1 "$tag.time")
  IFS=, read -r jw ls beams cycles msgs < <(python3 "$PY" fields "$tag.json")
  core=$(calc "round($user + $sys, 2)")
  nspb=""; [ -n "$beams" ] && nspb=$(calc "round($core * 1e9 / $beams, 1)")
  nspm=""; [ -n "$msgs" ] && nspm=$(calc "round($core * 1e9 / $msgs, 1)")
  echo "$row,$b,$rep,$wall,$ls,$beams,$core,$nspb,$(calc "round($rss / 1024, 1)"),,,$cycles,$jw,$msgs,$nspm,,$(threads_of "$args"),$user,$sys,\"$args\"" >> "$OUT"
  printf '  %-15s %-4s rep %s: wall %6.2f s  core %6.2f s  light %s s  beams %s  %s ns/beam  %s MiB\n' \
    "$row" "$b" "$rep" "$wall" "$core" "${ls:-—}" "${beams:-—}" "${nspb:-—}" "$(calc "round($rss / 1024)")" >&2
  [ -e "$row.ref.json" ] && check_same "$row.ref.json" "$tag.json" "$b rep $rep of $row" "base rep 1"
  [ -e "$row.ref.json" ] || cp "$tag.json" "$row.ref.json"
}

# One cachegrind run (--threads 1): appends its CSV line (instructions, counts; no timings).
cg_run() {   # row, binary label
  local row=$1 b=$2 tag="$1.$2.cg" args=${CG_ARGS[$1]:-"${ARGS[$1]} --threads 1"}
  local cmd=($args) t0 t1 ir jw ls beams cycles msgs ipb ipm ref
  read -ra outs <<< "$(out_args "${cmd[0]}" "$TMP/$tag")"
  t0=$(date +%s)
  valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file="$tag.cgout" \
    "${BIN[$b]}" "${cmd[@]}" "${outs[@]}" > "$tag.log" 2>&1 \
    || { tail -20 "$tag.log" >&2; die "$b failed under cachegrind on '$args' (log above)"; }
  t1=$(date +%s)
  ir=$(python3 "$PY" cgrefs "$tag.cgout")
  IFS=, read -r jw ls beams cycles msgs < <(python3 "$PY" fields "$tag.json")
  ipb=""; [ -n "$beams" ] && ipb=$(calc "round($ir / $beams, 1)")
  ipm=""; [ -n "$msgs" ] && ipm=$(calc "round($ir / $msgs, 1)")
  echo "$row,$b,cg,,,$beams,,,,$ir,$ipb,$cycles,,$msgs,,$ipm,1,,,\"$args\"" >> "$OUT"
  printf '  %-15s %-4s cachegrind (%s s): %s instr  %s instr/beam  %s instr/msg\n' \
    "$row" "$b" "$((t1 - t0))" "$ir" "${ipb:-—}" "${ipm:-—}" >&2
  # Same command as the row's but for --threads: its counts must be the row's too.
  if [ -z "${CG_ARGS[$row]:-}" ] && [ -e "$row.ref.json" ]; then ref="$row.ref.json"; else ref="$row.cgref.json"; fi
  [ -e "$ref" ] && check_same "$ref" "$tag.json" "the $b cachegrind run of $row" "$([ "$ref" = "$row.ref.json" ] && echo "base rep 1" || echo "the base cachegrind run")"
  [ -e "$row.cgref.json" ] || cp "$tag.json" "$row.cgref.json"
}

START=$(date +%s)
for row in "${SELECTED[@]}"; do
  echo "$row: ${ARGS[$row]}" >&2
  rs=$(date +%s)
  for ((rep = 1; rep <= REPS; rep++)); do
    for b in base new; do timed_run "$row" "$b" "$rep"; done
  done
  if [ "$CACHEGRIND" != 0 ] && [[ " $CG_ROWS " == *" $row "* ]]; then
    for b in base new; do cg_run "$row" "$b"; done
  fi
  echo "  $row: $(( $(date +%s) - rs )) s in all" >&2
done

# Header of the summary: what ran, on what, when.
ident() {   # label → "path (sha256 …, version …, commit …)"
  local bin=${BIN[$1]} rev_var=${1^^}_REV rev sha ver
  rev=${!rev_var:-}
  if [ -z "$rev" ]; then
    rev=$(git -C "$(dirname "$bin")" rev-parse --short HEAD 2>/dev/null || echo "unknown (binary not in a git tree; set ${1^^}_REV)")
  fi
  sha=$(sha256sum "$bin" | cut -c1-12)
  ver=$("$bin" --version 2>/dev/null | head -1 || true)
  echo "\`$bin\` (sha256 $sha…, \`${ver:-?}\`, commit $rev)"
}
repo_rev=$(git -C "$REPO" rev-parse --short HEAD 2>/dev/null || echo "?")
[ -n "$(git -C "$REPO" status --porcelain -uno 2>/dev/null)" ] && repo_rev="$repo_rev (uncommitted changes)"
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')
mem=$(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo)
{
  echo "## host-sim host cost: base → new"
  echo
  echo "* command: \`REPS=$REPS ROWS=\"${SELECTED[*]}\" CACHEGRIND=$CACHEGRIND bench/host_cost.sh $1 $2\`"
  echo "* base: $(ident base)"
  echo "* new: $(ident new)"
  echo "* repository: $REPO at $repo_rev"
  echo "* machine: $NPROC cores, $cpu, $mem; $(uname -r)"
  echo "* date: $(date -u '+%Y-%m-%d %H:%M UTC'); $(( $(date +%s) - START )) s in all"
} > "$TMP/header.md"
python3 "$PY" table "$OUT" "$TMP/header.md" | tee "$MD"
echo "host_cost: CSV $OUT, table $MD" >&2
