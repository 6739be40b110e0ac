#!/usr/bin/env bash
# Classic shadow rays under the thesis's rule with a shadow bias of K voxels (`render --thesis
# --lighting classic --shadow-bias K`), against the f64 reference, beside diffusion on the same
# thesis machine: shadow disagreement % / PSNR dB per scene, n and K. Writes
# bench-out/shadow_bias.csv and bench-out/shadow_bias.md (the table with its header).
#   SCENES default: "cornell bureau1 bureau2" (the Cornell box through its camera, as render does)
#   NS     default: "64 128"
#   KS     default: "0 1 2 3"
#   BIN    default: target/release/host-sim (built if absent)
set -euo pipefail
cd "$(dirname "$0")/.."
SCENES=${SCENES:-"cornell bureau1 bureau2"}
NS=${NS:-"64 128"}
KS=${KS:-"0 1 2 3"}
BIN=${BIN:-target/release/host-sim}
[[ -x $BIN ]] || cargo build --release -q -p host-sim
mkdir -p bench-out/shadow_bias
CSV=bench-out/shadow_bias.csv
echo "scene,n,method,k,shadow_disagreement_pct,psnr_db" > "$CSV"
one() { # scene n method k args...
  local s=$1 n=$2 m=$3 k=$4; shift 4
  "$BIN" render "$s" --n "$n" --thesis --reference --quiet "$@" \
    --out bench-out/shadow_bias/out.png --stats bench-out/shadow_bias/out.json 2>/dev/null
  python3 - "$s" "$n" "$m" "$k" bench-out/shadow_bias/out.json >> "$CSV" <<'PY'
import json, sys
r = json.load(open(sys.argv[5]))["reference"]
print(f"{sys.argv[1]},{sys.argv[2]},{sys.argv[3]},{sys.argv[4]},{r['shadow_disagreement_pct']:.4f},{r['psnr_db']:.4f}")
PY
}
for s in $SCENES; do
  for n in $NS; do
    for k in $KS; do one "$s" "$n" classic "$k" --lighting classic --shadow-bias "$k"; done
    one "$s" "$n" diffusion - 
  done
done
. bench/lib.sh
{
  bench_header "SCENES=\"$SCENES\" NS=\"$NS\" KS=\"$KS\" bash bench/shadow_bias.sh"
  echo
  KS=$KS python3 - "$CSV" <<'PY'
import csv, os, sys
rows = list(csv.DictReader(open(sys.argv[1])))
ks = os.environ["KS"].split()
cell = lambda r: f"{float(r['shadow_disagreement_pct']):.2f} / {float(r['psnr_db']):.2f}"
print("| scene | n | " + " | ".join(f"K = {k}" + (" (thesis)" if k == "0" else "") for k in ks) + " | diffusion (f = 0) |")
print("|---|---|" + "---|" * (len(ks) + 1))
keys = list(dict.fromkeys((r["scene"], r["n"]) for r in rows))
for s, n in keys:
    get = {(r["method"], r["k"]): r for r in rows if (r["scene"], r["n"]) == (s, n)}
    print(f"| {s} | {n} | " + " | ".join(cell(get[("classic", k)]) for k in ks) + f" | {cell(get[('diffusion', '-')])} |")
PY
} > bench-out/shadow_bias.md
cat bench-out/shadow_bias.md
