#!/usr/bin/env bash
# The cell's shading arithmetic (micromath + Newton steps, integer power, gamma table) against
# the same formula in f64 with libm over 10^6 random inputs: `cargo run --release -p cell-core
# --example micromath_error`. Writes bench-out/micromath.md (the table with its header).
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p bench-out
. bench/lib.sh
{
  bench_header "bash bench/micromath.sh"
  echo
  cargo run --release -q -p cell-core --example micromath_error | grep '^|'
} > bench-out/micromath.md
cat bench-out/micromath.md
