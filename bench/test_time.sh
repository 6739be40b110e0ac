#!/usr/bin/env bash
# The README's test command as a newcomer pays it, per commit: a fresh clone, then
# `cargo test --workspace --no-run` (the compile part, cargo's defaults: incremental, the
# profiles of Cargo.toml) and `CI=1 cargo test --workspace` (the run; with CI set a missing
# QEMU fails instead of skipping, so every test runs). The commits run one after another,
# REPS times, alternating the order (A B, B A, ...). Run it on a quiet machine.
#
# Usage: bench/test_time.sh REV [REV ...]    (env REPS=1, OUT=bench-out/test_time.csv;
#                                              the markdown table goes to ${OUT%.csv}.md;
#                                              TABLE_ONLY=1: only rewrite the table from OUT)
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: bench/test_time.sh REV [REV ...]" >&2; exit 2; }
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
REPS=${REPS:-1}
OUT=${OUT:-bench-out/test_time.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
WORK=$(mktemp -d)
# shellcheck source=bench/commits.sh
. "$REPO/bench/commits.sh"
trap 'rm -rf "$WORK"' EXIT
REVS=()
for r in "$@"; do REVS+=("$(git -C "$REPO" rev-parse --short "$r")"); done
if [ -z "${TABLE_ONLY:-}" ]; then
echo "commit,rep,build_s,run_s,total_s,tests_passed" > "$OUT"
for rep in $(seq 1 "$REPS"); do
  mapfile -t order < <(rep_order "$rep" "${REVS[@]}")
  for c in "${order[@]}"; do
    rm -rf "$WORK/clone"
    git clone -q "$REPO" "$WORK/clone"
    git -C "$WORK/clone" checkout -q --detach "$c"
    cd "$WORK/clone"
    build=$(seconds cargo test --workspace --no-run)
    run=$(CI=1 seconds cargo test --workspace)
    passed=$(grep -o '[0-9]* passed' "$WORK/log" | awk '{ s += $1 } END { print s }')
    total=$(echo "$build + $run" | bc)
    echo "$c,$rep,$build,$run,$total,$passed" >> "$OUT"
    echo "$c rep $rep: build ${build} s, run ${run} s, ${passed} tests passed" >&2
    cd "$REPO"
  done
done
rm -rf "$WORK/clone"
fi
python3 - "$OUT" "$(nproc)" "$(git -C "$REPO" rev-parse --short HEAD)" \
  "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')" > "${OUT%.csv}.md" <<'PY'
import csv, datetime, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
commits = list(dict.fromkeys(r["commit"] for r in rows))
reps = max(int(r["rep"]) for r in rows)
now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
print(f"`REPS={reps} bash bench/test_time.sh {' '.join(commits)}` (script at {sys.argv[3]}), {now}, "
      f"{sys.argv[2]} cores, {sys.argv[4]}, medians of {reps} fresh clone(s) per commit, alternating:")
print()
print("| commit | compile (`cargo test --workspace --no-run`), s | run (`CI=1 cargo test --workspace`), s | total, min | tests passed |")
print("|---|---|---|---|---|")
for c in commits:
    rs = [r for r in rows if r["commit"] == c]
    med = lambda k: statistics.median(float(r[k]) for r in rs)
    print(f"| {c} | {med('build_s'):.0f} | {med('run_s'):.0f} | {med('total_s') / 60:.1f} | {rs[0]['tests_passed']} |")
PY
cat "${OUT%.csv}.md"
