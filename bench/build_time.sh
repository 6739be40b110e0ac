#!/usr/bin/env bash
# What a build of each commit costs from nothing, as a fresh clone pays it: the wall time of a
# clean `cargo build --release -p host-sim` (dependencies included), the binary's code size
# (`size`: .text, and the file), and the wall time of a clean `cargo test --workspace --no-run`
# (the README's test command, compile part) in a second empty target directory. Each commit is
# checked out in its own worktree; the commits run one after another, twice by default, in
# alternating order (A B B A ...), so a slower minute of a shared machine does not fall on one
# side only. Run it on a quiet machine: it is the only thing that should use the cores.
#
# Usage: bench/build_time.sh REV [REV ...]    (env REPS=2, OUT=bench-out/build_time.csv;
#                                               the markdown table goes to ${OUT%.csv}.md)
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: bench/build_time.sh REV [REV ...]" >&2; exit 2; }
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
REPS=${REPS:-2}
OUT=${OUT:-bench-out/build_time.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
WORK=$(mktemp -d)
# shellcheck source=bench/commits.sh
. "$REPO/bench/commits.sh"
trap 'for w in "$WORK"/wt-*; do git -C "$REPO" worktree remove --force "$w" 2>/dev/null || true; done; rm -rf "$WORK"' EXIT
REVS=()
for r in "$@"; do
  short=$(git -C "$REPO" rev-parse --short "$r")
  git -C "$REPO" worktree add -q --detach "$WORK/wt-$short" "$short"
  REVS+=("$short")
done
echo "commit,rep,release_build_s,text_bytes,binary_bytes,test_build_s" > "$OUT"
for rep in $(seq 1 "$REPS"); do
  mapfile -t order < <(rep_order "$rep" "${REVS[@]}")
  for c in "${order[@]}"; do
    cd "$WORK/wt-$c"
    rm -rf "$WORK/target-rel" "$WORK/target-test"
    rel=$(CARGO_TARGET_DIR="$WORK/target-rel" seconds cargo build --release -p host-sim)
    bin="$WORK/target-rel/release/host-sim"
    text=$(size -A "$bin" | awk '$1 == ".text" { print $2 }')
    bytes=$(stat -c %s "$bin")
    test=$(CARGO_TARGET_DIR="$WORK/target-test" seconds cargo test --workspace --no-run)
    echo "$c,$rep,$rel,$text,$bytes,$test" >> "$OUT"
    echo "$c rep $rep: release ${rel} s, .text $text B, tests ${test} s" >&2
  done
done
rm -rf "$WORK/target-rel" "$WORK/target-test"
python3 - "$OUT" "$(nproc)" > "${OUT%.csv}.md" <<'PY'
import csv, datetime, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
commits = list(dict.fromkeys(r["commit"] for r in rows))
print(f"`bash bench/build_time.sh {' '.join(commits)}`, {datetime.date.today().isoformat()}, "
      f"{sys.argv[2]} cores, medians of {max(int(r['rep']) for r in rows)} clean builds per commit (alternating):")
print()
print("| commit | clean release build of host-sim, s | host-sim .text, MB | binary, MB | clean test build (`cargo test --workspace --no-run`), s |")
print("|---|---|---|---|---|")
for c in commits:
    rs = [r for r in rows if r["commit"] == c]
    med = lambda k: statistics.median(float(r[k]) for r in rs)
    print(f"| {c} | {med('release_build_s'):.0f} | {med('text_bytes') / 1e6:.2f} | {med('binary_bytes') / 1e6:.1f} | "
          f"{med('test_build_s'):.0f} |")
PY
cat "${OUT%.csv}.md"
