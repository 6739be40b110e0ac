#!/usr/bin/env bash
# The thesis's §4.4.3 experiments under rc2's timing and the thesis-timing variant
# (docs/DIFFUSION-TIMING.md): every published (N, FA) point, the "large enough" FIFO sweep,
# the 16³ time-lapse; then the comparison tables and growth exponents.
# Usage: bash bench/thesis-timing.sh        (writes bench-out/*.csv, *.png; ~30 min on 2 shared cores)
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p bench-out
cargo build --release -q -p host-sim
hs=./target/release/host-sim
# Every published point: rc2 and thesis timings with the source at the origin, rc2 at the centre.
$hs diffusion-table --published --timing rc2,thesis --policy thesis --source origin \
  --out bench-out/published-origin.csv --plot bench-out/published-origin.png --quiet
$hs diffusion-table --published --timing rc2 --policy thesis --source centre \
  --out bench-out/published-centre.csv --plot bench-out/published-centre.png --quiet
# FIFOs large enough: FA = 64, N = 4…64.
ns=$(seq -s, 4 64)
$hs diffusion-table --n "$ns" --fa 64 --timing thesis --policy thesis --source origin \
  --out bench-out/large.csv --plot bench-out/large.png --quiet
$hs diffusion-table --n "$ns" --fa 64 --timing rc2 --policy thesis --source centre \
  --out bench-out/large-centre.csv --plot bench-out/large-centre.png --quiet
# Emission order, x and y first against z first (§4.2.3, §4.4.3).
$hs diffusion-table --n 16,32,64,128 --fa 1,16,32 --timing thesis --policy thesis --source origin \
  --emission z-first --out bench-out/z-first.csv --plot bench-out/z-first.png --quiet
$hs diffusion-table --n 16,32,64,128 --fa 1,16,32 --timing rc2 --policy thesis --source centre \
  --emission z-first --out bench-out/z-first-centre.csv --plot bench-out/z-first-centre.png --quiet
# The 16³ time-lapse, source at the centre as in the thesis's figures.
$hs diffusion-table --n 16 --fa 1 --timing thesis --policy thesis --timelapse bench-out/timelapse.png \
  --out bench-out/timelapse.csv --plot bench-out/timelapse-table.png --quiet
python3 bench/thesis-timing.py bench-out
