#!/usr/bin/env bash
# Which pixels are still wrong, and why (BENCHMARKS.md, "How accurate is the image?"): for each
# scene and n, `lit_bounds SCENE N target0+cell64+source truth reference` and the same with
# `--refine` (tests/examples/lit_bounds.rs): the default render's wrong pixels (light 1) sorted
# by what the machine shows there, the PSNR with the reference's own lit flags and with `truth`,
# and the default with only its shadow-edge pixels re-tested.
# NS (default "128 256") and SCENES (default "cornell teapot-floor cow-floor bureau1") choose the
# runs; APPEND=1 adds their rows to the CSV's (the table then has both). Writes bench-out/wrong-pixels.csv (one line per scene and n) and bench-out/wrong-pixels.md
# (the table, with the command, commit, machine and date; raw outputs in bench-out/wrong-pixels/).
set -euo pipefail
cd "$(dirname "$0")/.."
NS=${NS:-"128 256"}
SCENES=${SCENES:-"cornell teapot-floor cow-floor bureau1"}
cargo build --release -q -p rc2-tests --example lit_bounds
X=${CARGO_TARGET_DIR:-target}/release/examples/lit_bounds
D=bench-out/wrong-pixels
mkdir -p "$D"
CSV=bench-out/wrong-pixels.csv
[[ ${APPEND:-0} == 1 && -f $CSV ]] || echo "scene,n,wrong,light,coincident,edge,other,psnr_default_db,psnr_reference_flags_db,psnr_truth_db,refined_disagreement_pct,refined_psnr_db,refined_pixels,wall_s" > "$CSV"
for n in $NS; do
  for scene in $SCENES; do
    o=$D/$scene-$n
    t0=$(date +%s.%N)
    $X "$scene" "$n" target0+cell64+source truth reference > "$o.out" 2> "$o.err"
    $X "$scene" "$n" target0+cell64+source truth reference --refine > "$o.refine.out" 2> "$o.refine.err"
    t1=$(date +%s.%N)
    python3 - "$o" "$scene" "$n" "$(echo "$t1 - $t0" | bc)" >> "$CSV" <<'PY'
import re, sys
o, scene, n, wall = sys.argv[1:]
pat = re.compile(r"^\s*(\S+)\s+([\d.]+) %\s+([-\d.inf]+) dB\s+(\d+) / (\d+)\s+\(light (\d+), coincident (\d+), edge (\d+), other (\d+)\)")
def lines(path):
    return {m.group(1): m for m in map(pat.match, open(path)) if m}
plain, refined = lines(o + ".out"), lines(o + ".refine.out")
d = plain["target0+cell64+source"]
why = [int(d.group(i)) for i in (6, 7, 8, 9)]
r = refined["target0+cell64+source"]
count = int(re.search(r"refined (\d+) pixels", open(o + ".refine.err").read()).group(1))  # the first variant's
print(",".join(map(str, [scene, n, sum(why), *why, d.group(3), plain["reference"].group(3), plain["truth"].group(3),
                         r.group(2), r.group(3), count, f"{float(wall):.1f}"])))
PY
    tail -1 "$CSV"
  done
done
. bench/lib.sh
{
  bench_header "${APPEND:+APPEND=$APPEND }NS=\"$NS\" SCENES=\"$SCENES\" bash bench/wrong_pixels.sh  (lit_bounds SCENE N target0+cell64+source truth reference, then the same with --refine)"
  echo
  python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
rows.sort(key=lambda r: (["cornell", "teapot-floor", "cow-floor", "bureau1"].index(r["scene"])
                         if r["scene"] in ("cornell", "teapot-floor", "cow-floor", "bureau1") else 9, r["scene"], int(r["n"])))
sp = lambda v: f"{int(v):,}".replace(",", " ")
print("| scene | n | wrong pixels | light | coincident | edge | other | PSNR, reference's flags | PSNR, `truth` | edges re-tested (pixels) |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r['scene']} | {r['n']} | {sp(r['wrong'])} | {sp(r['light'])} | {r['coincident']} | {r['edge']} | {r['other']} | "
          f"{float(r['psnr_reference_flags_db']):.1f} dB | {float(r['psnr_truth_db']):.1f} dB | "
          f"{float(r['refined_disagreement_pct']):.2f} % / {float(r['refined_psnr_db']):.1f} dB ({sp(r['refined_pixels'])}) |")
PY
} | tee bench-out/wrong-pixels.md
