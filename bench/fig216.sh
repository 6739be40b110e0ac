#!/usr/bin/env bash
# The radiosity thesis's Fig. 2.16 (§2.5.3, "Temps de calcul"): host time per shot of form
# factors by the hemicube and by the projection disk at equivalent resolutions, on the office
# scenes. The thesis ran both on a Sparc LX; only the ratio carries.
#
# Equivalent resolutions are Table 2.1's criterion, as `host-sim form-factors` finds them: for
# each hemicube resolution R the disk's resolution is read from the figure CSV (`--figure-csv`,
# column `resolution` of the disk's rows at `hemicube_r` = R), or for Table 2.1's rows (100,
# 200, 400, 600, 800, 1000) from the tables CSV (`--tables --csv`). Each run is `host-sim radiosity
# SCENE --reference --form-factors METHOD:RES --shots SHOTS`: the f64 reference's progressive
# solution computes each shot's row of form factors with that surface (3 × 3 sample points of
# the shooting patch, one projection of the whole scene each); its wall time over its shots is
# the time per shot. The grid's own solution (n = N, small) runs too and is not timed here.
# Hemicube and disk runs alternate, REPS times each. classe is left out by default: each run
# also solves the reference's direct light alone (one row per emitting patch, 260 in classe),
# minutes per run from R = 400 on a 2-core machine (`SCENES=classe RS="16 100 200 400"`).
#
# Usage: bench/fig216.sh BIN   (env SCENES="bureau1 bureau2", RS="16 64 100 200 400",
#                               SHOTS=12, N=32, REPS=1, OUT=bench-out/fig216.csv; the table
#                               goes to ${OUT%.csv}.md)
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: bench/fig216.sh BIN" >&2; exit 2; }
BIN=$(realpath "$1")
SCENES=${SCENES:-bureau1 bureau2}
RS=${RS:-16 64 100 200 400}
SHOTS=${SHOTS:-12}
N=${N:-32}
REPS=${REPS:-1}
OUT=${OUT:-bench-out/fig216.csv}
mkdir -p "$(dirname "$OUT")"
OUT=$(realpath "$OUT")
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cd "$WORK"

"$BIN" form-factors --figure "$WORK/fig.png" --figure-csv "$WORK/eq.csv" > /dev/null
"$BIN" form-factors --tables --csv "$WORK/tables.csv" > /dev/null
# The disk's resolution equivalent to hemicube R: from the figure CSV (every even R in 16..=96),
# else from Table 2.1 (R = 100, 200, 400, 600, 800, 1000: the disk's cell in the hemicube's row).
disk_res() {
  awk -F, -v r="$1" 'NR > 1 && $3 == "disk" && $4 == r { print $5; exit }' "$WORK/eq.csv" | grep . ||
    awk -F, -v r="$1" '$1 == "2.1" && $3 == "hemicube" && $4 == r { ref = $2 }
                       $1 == "2.1" && $3 == "disk" && $2 == ref && ref != "" { print $4; exit }' "$WORK/tables.csv"
}

echo "scene,hemicube_r,method,resolution,rep,shots,reference_seconds,seconds_per_shot" > "$OUT"
for scene in $SCENES; do
  for r in $RS; do
    d=$(disk_res "$r")
    [ -n "$d" ] || { echo "no disk resolution equivalent to hemicube R = $r (even R in 16..=96, or a Table 2.1 row)" >&2; exit 1; }
    for rep in $(seq 1 "$REPS"); do
      for spec in "hemicube:$r" "disk:$d"; do
        "$BIN" radiosity "$scene" --n "$N" --shots "$SHOTS" --reference --form-factors "$spec" \
          --stats "$WORK/s.json" --quiet > "$WORK/log" 2>&1 || { tail -20 "$WORK/log" >&2; exit 1; }
        python3 - "$WORK/s.json" "$scene" "$r" "$spec" "$rep" >> "$OUT" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))["reference"]
method, res = sys.argv[4].split(":")
print(f"{sys.argv[2]},{sys.argv[3]},{method},{res},{sys.argv[5]},{s['shots']},{s['wall_seconds']:.3f},"
      f"{s['wall_seconds'] / max(s['shots'], 1):.4f}")
PY
        tail -1 "$OUT" >&2
      done
    done
  done
done

python3 - "$OUT" "$(git -C "$REPO" rev-parse --short HEAD)$(git -C "$REPO" diff --quiet HEAD || echo " + uncommitted changes")" "$("$BIN" --version)" "$(nproc)" \
  "$SCENES" "$RS" "$SHOTS" "$N" "$REPS" > "${OUT%.csv}.md" <<'PY'
import csv, datetime, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
commit, version, cores, scenes, rs, shots, n, reps = sys.argv[2:]
now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
print(f'`SCENES="{scenes}" RS="{rs}" SHOTS={shots} N={n} REPS={reps} bash bench/fig216.sh BIN` '
      f"({version}, commit {commit}), {now}, {cores} cores; seconds per shot of the f64 reference, "
      f"medians of {reps} run(s):")
print()
print("| scene | hemicube R | hemicube s/shot | disk resolution | disk s/shot | disk / hemicube |")
print("|---|---|---|---|---|---|")
key = lambda r: (r["scene"], int(r["hemicube_r"]))
for s, r in dict.fromkeys(key(x) for x in rows):
    per = {m: [x for x in rows if key(x) == (s, r) and x["method"] == m] for m in ("hemicube", "disk")}
    med = {m: statistics.median(float(x["seconds_per_shot"]) for x in v) for m, v in per.items()}
    print(f"| {s} | {r} | {med['hemicube']:.3f} | {per['disk'][0]['resolution']} | {med['disk']:.3f} | "
          f"{med['disk'] / med['hemicube']:.2f} |")
PY
cat "${OUT%.csv}.md"
