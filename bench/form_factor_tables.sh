#!/usr/bin/env bash
# The radiosity thesis's Tables 2.1-2.3 (§2.5: equivalent resolutions, proxels used, memory in Mo)
# computed by `host-sim form-factors --tables` from each projective method's own surface, beside
# the published values. Writes bench-out/form_factor_tables.csv and prints the markdown tables of
# docs/FORM-FACTORS.md and BENCHMARKS.md: a cell is `computed` where it equals the published value,
# else `computed (published)`, in bold where it is more than one unit of the last digit away; the
# last column, beams, is the grid's shot (nothing published).
# Closed forms only: seconds in any profile (PROFILE=dev to skip the release build).
set -euo pipefail
cd "$(dirname "$0")/.."
PROFILE=${PROFILE:-release}
mkdir -p bench-out
cargo build -q -p host-sim --profile "$PROFILE"
DIR=$([ "$PROFILE" = dev ] && echo debug || echo "$PROFILE")
B=${CARGO_TARGET_DIR:-target}/$DIR/host-sim
CSV=bench-out/form_factor_tables.csv
$B form-factors --tables --csv "$CSV" > bench-out/form_factor_tables.txt 2>/dev/null
echo "commit $(git rev-parse --short HEAD), $(date -u +%F), $(nproc) cores: host-sim form-factors --tables --csv $CSV"
python3 - "$CSV" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
methods = list(dict.fromkeys(r["method"] for r in rows))  # the thesis's six, then the grid's shot (beams)
titles = {"2.1": "Table 2.1: equivalent resolutions", "2.2": "Table 2.2: proxels used", "2.3": "Table 2.3: memory (Mo = 10^6 bytes)"}
def far(c, p):
    a, b = c.split("/"), p.split("/")
    unit = 10 ** -(len(p.split(".")[1]) if "." in p else 0)
    return any(abs(float(x) - float(y)) > unit * (1 + 1e-9) for x, y in zip(a, b))
for t, title in titles.items():
    print(f"\n{title}\n")
    print("| " + ("reference form factor" if t == "2.1" else "hemicube R") + " | " + " | ".join(methods) + " |")
    print("|---" * (len(methods) + 1) + "|")
    keys = list(dict.fromkeys(r["reference"] for r in rows if r["table"] == t))
    for k in keys:
        cells = {r["method"]: r for r in rows if r["table"] == t and r["reference"] == k}
        out = []
        for m in methods:
            c, p = cells[m]["computed"], cells[m]["published"]
            if not p:  # nothing published (the grid's shot)
                out.append(c)
                continue
            s = c if c == p else f"{c} ({p})"
            out.append(f"**{s}**" if far(c, p) else s)
        print(f"| {k} | " + " | ".join(out) + " |")
PY
