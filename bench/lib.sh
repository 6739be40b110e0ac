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

# The plain build and the `mpi` build of host-sim, each under its own name in $1
# (host-sim-plain, host-sim-mpi: two builds of one target folder), unless SKIP_BUILD=1; and
# the variables without which mpirun refuses root (CI's machine runs as root).
mpi_binaries() {
  if [[ ${SKIP_BUILD:-0} != 1 ]]; then
    cargo build --release -q -p host-sim
    cp target/release/host-sim "$1/host-sim-plain"
    cargo build --release -q -p host-sim --features mpi
    cp target/release/host-sim "$1/host-sim-mpi"
  fi
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
}
