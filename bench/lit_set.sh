#!/usr/bin/env bash
# What `light` reports: its lit set against exact f64 visibility on meshes it was never tuned on.
# Each mesh of MESHES under each light of LIGHTS at each n of NS, by `light-accuracy` (every
# surface voxel: lit by the machine vs its centre seeing the light in f64, its own face
# ignored), under each lit rule of RULES. Writes bench-out/lit_set.csv (one row per run) and
# bench-out/lit_set.md (mean and worst disagreement per rule and n, with the command, commit,
# machine and date).
#   MESHES  default: suzanne fandisk cow teapot (../shared/scenes/NAME.obj, or any path)
#   LIGHTS  default: 0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9 (grid-normalised)
#   NS      default: "64 128 256"
#   RULES   default: "exact plane" (exact: what `light` runs; plane: --lit-rule plane, rays from
#           the source voxel)
#   BIN     default: target/release/host-sim (built if absent)
#   TABLE_ONLY=1 rewrites bench-out/lit_set.md from the CSV without running (same variables)
set -euo pipefail
cd "$(dirname "$0")/.."
MESHES=${MESHES:-"suzanne fandisk cow teapot"}
LIGHTS=${LIGHTS:-"0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9"}
NS=${NS:-"64 128 256"}
RULES=${RULES:-"exact plane"}
BIN=${BIN:-target/release/host-sim}
[[ -x $BIN || ${TABLE_ONLY:-0} == 1 ]] || cargo build --release -q -p host-sim
mkdir -p bench-out/lit_set
CSV=bench-out/lit_set.csv
if [[ ${TABLE_ONLY:-0} != 1 ]]; then
echo "mesh,light,n,rule,surface_voxels,false_lit,false_dark,disagreement_pct,cycles" > "$CSV"
for m in $MESHES; do
  obj=$m; [[ -f $obj ]] || obj=../shared/scenes/$m.obj
  for l in $LIGHTS; do
    for n in $NS; do
      for r in $RULES; do
        out=bench-out/lit_set/run.csv
        "$BIN" light-accuracy "$obj" --n "$n" --frac-bits 0 --policy radial --lit-rule "$r" --light "$l" --out "$out" 2>/dev/null
        # scene,n,frac_bits,surface_voxels,lit_discrete,lit_continuous,false_lit,false_dark,disagreement_pct,cycles,...
        tail -n 1 "$out" | awk -F, -v m="$(basename "$m" .obj)" -v l="$l" -v r="$r" \
          '{printf "%s,\"%s\",%s,%s,%s,%s,%s,%s,%s\n", m, l, $2, r, $4, $7, $8, $9, $10}' >> "$CSV"
      done
    done
  done
done
fi
MESHES=$MESHES LIGHTS=$LIGHTS NS=$NS python3 - "$CSV" <<'PY' > bench-out/lit_set.md
import csv, subprocess, sys, platform, datetime, collections, os
rows = list(csv.DictReader(open(sys.argv[1])))
by = collections.defaultdict(list)
for r in rows:
    by[(r["rule"], int(r["n"]))].append(r)
rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), platform.machine())
env = " ".join(f'{k}="{os.environ[k]}"' for k in ("MESHES", "LIGHTS", "NS"))
print(f"`{env} bash bench/lit_set.sh` (f = 0), commit {rev}, {cpu}, {datetime.date.today()}: "
      "surface voxels whose lit state differs from f64 visibility of their centre (`light-accuracy`).\n")
print("| lit rule | n | runs | surface voxels (mean) | disagreement % mean | worst (mesh, light) |")
print("|---|---|---|---|---|---|")
for (rule, n) in sorted(by, key=lambda k: (k[0] != "exact", k[0], k[1])):
    rs = by[(rule, n)]
    d = [float(r["disagreement_pct"]) for r in rs]
    w = max(rs, key=lambda r: float(r["disagreement_pct"]))
    sv = sum(int(r["surface_voxels"]) for r in rs) / len(rs)
    print(f"| {rule} | {n} | {len(rs)} | {sv:.0f} | {sum(d)/len(d):.2f} | {max(d):.2f} ({w['mesh']}, {w['light']}) |")
PY
cat bench-out/lit_set.md
