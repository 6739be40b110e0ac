#!/usr/bin/env bash
# rc2 against outside tools in one run: voxelization against trimesh and Open3D,
# lighting against exact shadow rays with Embree (embreex). Creates a Python venv under
# bench-out/venv (gitignored) and installs trimesh, numpy, open3d, embreex from PyPI.
# Writes bench-out/compare/{voxelize,light}.csv; see bench/compare.py for what is measured.
#
# Usage: bash bench/compare.sh [compare.py options]   e.g. --n 128 256 --runs 5, --only light
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p bench-out
cargo build --release -q -p host-sim
VENV=bench-out/venv
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q --upgrade pip
fi
# open3d publishes wheels for CPython 3.8–3.12 on x86-64 Linux; without one, the comparison
# falls back to trimesh alone (compare.py reports which tools ran).
"$VENV/bin/pip" install -q trimesh numpy scipy embreex
"$VENV/bin/pip" install -q open3d || echo "note: no open3d wheel for this Python; trimesh only" >&2
. bench/lib.sh
bench_header "bash bench/compare.sh $*"
exec "$VENV/bin/python" bench/compare.py --host ./target/release/host-sim "$@"
