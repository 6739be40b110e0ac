#!/usr/bin/env bash
# Run time against error: BENCHMARKS.md's Pareto table and docs/pareto.png.
# Runs `host-sim bench --n N --view fitted --frac-bits F --out bench-out/bench.csv --plot
# bench-out/bench.png` (the knob sweep on cornell, teapot-floor and cow-floor; N=128, F=0,1 by
# default) and writes bench-out/bench.md: the command, commit, machine and date, and one row
# per configuration (means over the scenes, from the CSV's `all` rows and host-sim's own table
# of labels), in the sweep's order. COPY=1 also copies the plot to docs/pareto.png.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${N:-128}
F=${F:-0,1}
mkdir -p bench-out
cargo build --release -q -p host-sim
B=${CARGO_TARGET_DIR:-target}/release/host-sim
cmd="host-sim bench --n $N --view fitted --frac-bits $F --out bench-out/bench.csv --plot bench-out/bench.png"
t0=$(date +%s)
$B bench --n "$N" --view fitted --frac-bits "$F" --out bench-out/bench.csv --plot bench-out/bench.png 2> bench-out/bench.log
t1=$(date +%s)
[ "${COPY:-0}" = 1 ] && cp bench-out/bench.png docs/pareto.png
. bench/lib.sh
{
  bench_header "N=$N F=$F bash bench/pareto.sh  ($cmd)"
  echo "* the sweep took $(( (t1 - t0) / 60 )) min $(( (t1 - t0) % 60 )) s (host wall seconds per run are in bench-out/bench.csv)"
  echo
  # host-sim's own table (stderr) gives the labels; the figures are re-read from the CSV's
  # `all` rows, row for row in the sweep's order.
  python3 - bench-out/bench.csv bench-out/bench.log <<'PY'
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["scene"] == "all"]
labels = []
for line in open(sys.argv[2]):
    if line.startswith("| ") and not line.startswith("| knobs"):
        labels.append(line.split("|")[1].strip())
assert len(labels) == len(rows), (len(labels), len(rows))
sp = lambda v: f"{v:,}".replace(",", " ")
print("| knobs (default: exact occluders, rays from the light, f = 0, standard, conservative, facet normals, FA = 16, radial) "
      "| mean cycles | mean shadow disagreement % | mean PSNR dB | bytes/cell | on the front |")
print("|---|---|---|---|---|---|")
for label, r in zip(labels, rows):
    print(f"| {label} | {sp(round(float(r['cycles'])))} | {float(r['shadow_disagreement_pct']):.2f} | "
          f"{float(r['psnr_db']):.2f} | {sp(int(r['bytes_per_cell']))} | {'yes' if r['pareto'] == 'true' else ''} |")
PY
} | tee bench-out/bench.md
