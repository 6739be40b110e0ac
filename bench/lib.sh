# Sourced by the bench scripts (`. bench/lib.sh`): what every table in BENCHMARKS.md carries.

# bench_header COMMAND: the lines above a table — the command that wrote it, the commit it was
# built from (and whether the tree had changes), the machine and the date.
bench_header() {
  local dirty
  dirty=$(git diff --quiet HEAD -- . 2> /dev/null || echo " (uncommitted changes)")
  echo "* command: \`$1\`"
  echo "* commit: $(git rev-parse --short HEAD)$dirty"
  echo "* machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo); $(uname -r)"
  echo "* date: $(date -u '+%F %H:%M UTC')"
}
