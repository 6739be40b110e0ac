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
#   Grazing: the light less than 15 degrees from a voxel's face plane (light-accuracy's
#   grazing_voxels); the table gives the disagreement with and without those voxels.
#   MEASURES default: "centre" (light-accuracy --measure: centre, entry, reach — where on the
#           segment from the light to a voxel's centre its f64 visibility is taken)
#   F       default: 1, the `light` preset's fraction bits (host-sim/src/config/mod.rs,
#           LIGHT_FRAC_BITS); several, e.g. "0 1", give a row per f
#   BIN     default: target/release/host-sim (built if absent)
#   TABLE_ONLY=1 rewrites bench-out/lit_set.md from the CSV without running (same variables)
set -euo pipefail
cd "$(dirname "$0")/.."
MESHES=${MESHES:-"suzanne fandisk cow teapot"}
LIGHTS=${LIGHTS:-"0.2,0.9,0.1 0.9,0.5,0.2 0.5,0.05,0.5 0.1,0.2,0.9"}
NS=${NS:-"64 128 256"}
RULES=${RULES:-"exact plane"}
MEASURES=${MEASURES:-"centre"}
F=${F:-1}
BIN=${BIN:-target/release/host-sim}
[[ -x $BIN || ${TABLE_ONLY:-0} == 1 ]] || cargo build --release -q -p host-sim
mkdir -p bench-out/lit_set
CSV=bench-out/lit_set.csv
if [[ ${TABLE_ONLY:-0} != 1 ]]; then
echo "mesh,light,n,f,rule,measure,surface_voxels,false_lit,false_dark,disagreement_pct,cycles,grazing_voxels,grazing_disagreements,disagreement_pct_not_grazing" > "$CSV"
for m in $MESHES; do
  obj=$m; [[ -f $obj ]] || obj=../shared/scenes/$m.obj
  for l in $LIGHTS; do
    for n in $NS; do
      for f in $F; do
      for r in $RULES; do
        for me in $MEASURES; do
          out=bench-out/lit_set/run.csv
          "$BIN" light-accuracy "$obj" --n "$n" --frac-bits "$f" --policy radial --lit-rule "$r" --light "$l" --measure "$me" --out "$out" 2>/dev/null
          # scene,n,frac_bits,surface_voxels,lit_discrete,lit_continuous,false_lit,false_dark,disagreement_pct,cycles,
          # lower_bound,beams_processed,wall_seconds,measure,grazing_voxels,grazing_disagreements,disagreement_pct_not_grazing
          tail -n 1 "$out" | awk -F, -v m="$(basename "$m" .obj)" -v l="$l" -v r="$r" \
            '{printf "%s,\"%s\",%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s\n", m, l, $2, $3, r, $14, $4, $7, $8, $9, $10, $15, $16, $17}' >> "$CSV"
        done
      done
      done
    done
  done
done
fi
. bench/lib.sh
{
  bench_header "MESHES=\"$MESHES\" LIGHTS=\"$LIGHTS\" NS=\"$NS\" F=\"$F\" RULES=\"$RULES\" MEASURES=\"$MEASURES\" bash bench/lit_set.sh"
  echo
  python3 - "$CSV" <<'PY'
import csv, sys, collections
rows = list(csv.DictReader(open(sys.argv[1])))
by = collections.defaultdict(list)
for r in rows:
    by[(r["rule"], r.get("measure", "centre"), int(r["f"]), int(r["n"]))].append(r)
order = {"centre": 0, "entry": 1, "reach": 2}
print("| lit rule | measured at | f | n | runs | cycles (mean) | surface voxels (mean) | disagreement % mean | worst (mesh, light) | grazing voxels % | disagreement % mean, not grazing | worst, not grazing |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for (rule, me, f, n) in sorted(by, key=lambda k: (k[0] != "exact", k[0], order.get(k[1], 9), -k[2], k[3])):
    rs = by[(rule, me, f, n)]
    d = [float(r["disagreement_pct"]) for r in rs]
    w = max(rs, key=lambda r: float(r["disagreement_pct"]))
    sv = sum(int(r["surface_voxels"]) for r in rs) / len(rs)
    cy = sum(int(r["cycles"]) for r in rs) / len(rs)
    g = [100 * int(r["grazing_voxels"]) / max(1, int(r["surface_voxels"])) for r in rs]
    e = [float(r["disagreement_pct_not_grazing"]) for r in rs]
    we = max(rs, key=lambda r: float(r["disagreement_pct_not_grazing"]))
    print(f"| {rule} | {me} | {f} | {n} | {len(rs)} | {cy:.0f} | {sv:.0f} | {sum(d)/len(d):.2f} | {max(d):.2f} ({w['mesh']}, {w['light']}) "
          f"| {sum(g)/len(g):.1f} | {sum(e)/len(e):.2f} | {max(e):.2f} ({we['mesh']}, {we['light']}) |")
PY
} > bench-out/lit_set.md
cat bench-out/lit_set.md
