# Shared by the scripts that time whole commits (bench/build_time.sh, bench/test_time.sh);
# source it after setting WORK (a scratch directory).

# Run "$@" with its output in $WORK/log; print its wall seconds. On failure: the log's tail,
# then exit.
seconds() {
  local s
  s=$(date +%s.%N)
  "$@" > "$WORK/log" 2>&1 || { tail -30 "$WORK/log" >&2; exit 1; }
  echo "$(date +%s.%N) - $s" | bc
}

# The commits in the order repetition REP runs them: as given on odd repetitions, reversed on
# even ones (A B, B A, ...), so a slow minute of a shared machine does not fall on one side only.
# Usage: mapfile -t order < <(rep_order REP REV...)
rep_order() {
  local rep=$1 i
  shift
  local revs=("$@")
  if [ $((rep % 2)) -eq 0 ]; then
    for ((i = ${#revs[@]} - 1; i >= 0; i--)); do echo "${revs[$i]}"; done
  else
    printf '%s\n' "${revs[@]}"
  fi
}
