#!/usr/bin/env bash
# Golden check: a host speed-up must change nothing the simulated machine does.
#
#   bash bench/golden.sh record  BIN DIR   run the golden set with BIN, write every output into DIR
#   bash bench/golden.sh compare BIN DIR   run it again with BIN into a temp dir and compare with DIR
#                                          byte for byte (cmp); exit 1 listing every differing file
#
# BIN is a built host-sim binary (e.g. target/release/host-sim). Each run works in an empty
# scratch directory with its outputs named out.*; every file it writes is kept as DIR/LABEL.*:
#   LABEL.png (+ .reference.png, .diff.png, .direct.png)   images
#   LABEL.stats.json      --stats with every timing/memory key removed (names containing wall,
#                         seconds, rss, time, elapsed, duration, or ending _ms/_us/_ns/_secs),
#                         keys sorted, canonical JSON
#   LABEL.lit.csv         light --lit-out;   LABEL.patches.csv, .shots.csv, .residual.png: radiosity
#   LABEL.summary.txt     the printed summary (stderr) with the timings removed (`wall …` fields,
#                         and any other "N.NN s" seconds value); LABEL.stdout.txt: stdout, same filter
#   manifest.txt          LABEL: command line of each run (compared too: same golden set)
#   info.txt              binary, date and run times (not compared)
# The runs `threads1` and `threads2` (--threads 1 / 2) must also give identical files: results
# never depend on the host's threads. Every other run uses --threads 2.
# Total 35-40 s on a 2-core machine (busy); the runs themselves about 20 s. HEAVY=1: see RUNS.
set -u -o pipefail

usage() {
    sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}
[ $# -eq 3 ] || usage
MODE=$1
BIN=$2
DIR=$3
case "$MODE" in record | compare) ;; *) usage ;; esac
[ -x "$BIN" ] || { echo "golden: $BIN is not an executable" >&2; exit 2; }
command -v python3 >/dev/null || { echo "golden: needs python3" >&2; exit 2; }
BIN=$(cd "$(dirname "$BIN")" && pwd)/$(basename "$BIN")

# The golden set: LABEL JOB ARGS... (--threads 2 added unless the run gives --threads).
RUNS=(
    # render: the default Cornell box through its camera, with the f64 reference
    "cornell128-ref   render --n 128 --reference"
    "fitted64         render --n 64 --view fitted"
    "teapot64         render teapot-floor --n 64"
    "cow64            render cow-floor --n 64"
    "bureau1-64       render bureau1 --n 64"
    "bureau1-128      render bureau1 --n 128"
    "bureau2-64       render bureau2 --n 64"
    "classe32         render classe --n 32"
    # other lit rules and engine paths
    "plane64          render --n 64 --lit-rule plane --rays-from voxel"
    "thesis64         render --n 64 --lit-rule thesis --rays-from voxel --sigma naive --contour projected --policy wavefront"
    "frac1-64         render --n 64 --frac-bits 1"
    "refined64        render --n 64 --lighting refined"
    "classic48        render --n 48 --lighting classic"
    "classic48-t26    render --n 48 --lighting classic --lit-rule thesis --ray-connectivity 26 --route dor --emitters all"
    "classic48-plane  render --n 48 --lighting classic --lit-rule plane --route dor --emitters all --shadow-bias 1"
    "mirror64         render cornell-mirror --n 64 --reflections 2"
    "hold4-64         render --n 64 --hold 4"
    "hold4-wave64     render --n 64 --hold 4 --policy wavefront"
    "stepall64        render --n 64 --stepping all-cells"
    "blocks8-64       render --n 64 --frustum-blocks 8"
    "pthesis64        render --n 64 --policy thesis"
    "faceN64          render --n 64 --normals face"
    "skipfrustum64    render --n 64 --lit-visible-only false --skip-hidden false --skip-frustum true"
    "faults64         render --n 64 --link-faults corrupt=0.01,drop=0.01,delay=0.05,seed=7"
    "radrender32      render --n 32 --radiosity --residual 0.1"
    # light: lit sets
    "light64          light --n 64"
    "light-f0-64      light --n 64 --frac-bits 0"
    "light-cow64      light cow-floor --n 64"
    "light-plane64    light --n 64 --lit-rule plane --rays-from voxel"
    "light-faults64   light --n 64 --link-faults corrupt=0.01,drop=0.01,seed=3"
    "light-wave48     light --n 48 --policy wavefront"
    "light-pthesis48  light --n 48 --policy thesis"
    "light-classic48  light --n 48 --lighting classic"
    "light-frustum64  light --n 64 --skip-frustum true"
    # radiosity: per-patch and per-shot CSVs, residual plot
    "rad32            radiosity cornell --n 32 --residual 0.1 --reference"
    "rad32-shots20    radiosity cornell --n 32 --shots 20"
    # results never depend on threads: these two must give identical files
    "threads1         render --n 32 --threads 1"
    "threads2         render --n 32 --threads 2"
)
# HEAVY=1 adds larger grids (about 40 s more): more cycles, merges, per-ray visits and busy
# links than the n <= 128 runs reach.
if [ "${HEAVY:-0}" = 1 ]; then
    RUNS+=(
        "cornell256       render --n 256"
        "teapot256        render teapot-floor --n 256"
        "bureau1-256      render bureau1 --n 256"
        "bureau2-128      render bureau2 --n 128"
        "fandisk128       render fandisk --n 128"
        "light-cow128     light cow-floor --n 128"
        "light-plane128   light bureau1 --n 128 --lit-rule plane --rays-from voxel"
        "classe64         render classe --n 64"
    )
fi

# finish SCRATCH OUT LABEL...: one python pass over every run's raw outputs in SCRATCH/LABEL/
# (stdout, stderr, w/ = the files it wrote) into OUT/LABEL.*:
#  * stats JSON: drop timing/memory keys at every depth (names containing wall, seconds, secs,
#    rss, time, elapsed, duration, or ending _ms/_us/_ns), sort keys, canonical form;
#  * printed text: drop `wall N s (…)` fields and any other "N.NN s" seconds value
#    ("…, 0.5 s", "(0.6 s)"), progress-bar carriage returns, and lines left empty;
#  * every other file copied as is: out.X -> LABEL.X (anything else: LABEL.NAME).
finish() {
    python3 - "$@" <<'PY'
import json, os, re, shutil, sys
scratch, out, labels = sys.argv[1], sys.argv[2], sys.argv[3:]
DROP = re.compile(r"wall|seconds|secs|rss|time|elapsed|duration|(^|_)(ms|us|ns)$", re.I)

def clean(v):
    if isinstance(v, dict):
        return {k: clean(x) for k, x in v.items() if not DROP.search(k)}
    if isinstance(v, list):
        return [clean(x) for x in v]
    return v

def strip_text(src, dst):
    with open(src, encoding="utf-8", errors="surrogateescape") as f:
        lines = f.read().split("\n")
    kept = []
    for line in lines:
        line = line.split("\r")[-1]
        s = re.sub(r"[ ,]*\bwall\b:? *[0-9.]+ *(s|ms|µs|us)\b( *\([^)]*\))?", "", line)
        s = re.sub(r" *\([0-9]+\.[0-9]+ ?(s|ms|µs|us)\)", "", s)
        s = re.sub(r",? *\b[0-9]+\.[0-9]+ ?(s|ms|µs|us)\b", "", s)
        if s.strip() or not line.strip():
            kept.append(s.rstrip())
    while kept and not kept[-1]:
        kept.pop()
    with open(dst, "w", encoding="utf-8", errors="surrogateescape") as f:
        f.write("\n".join(kept) + ("\n" if kept else ""))

bad = 0
for label in labels:
    d = os.path.join(scratch, label)
    strip_text(os.path.join(d, "stderr"), os.path.join(out, label + ".summary.txt"))
    strip_text(os.path.join(d, "stdout"), os.path.join(out, label + ".stdout.txt"))
    for name in sorted(os.listdir(os.path.join(d, "w"))):
        src = os.path.join(d, "w", name)
        dst = os.path.join(out, label + "." + (name[4:] if name.startswith("out.") else name))
        if name.endswith(".json"):
            try:
                with open(src) as f:
                    data = json.load(f)
            except ValueError as e:
                print(f"golden: {label}: bad JSON {name}: {e}", file=sys.stderr)
                shutil.copyfile(src, dst)
                bad = 1
                continue
            with open(dst, "w") as f:
                f.write(json.dumps(clean(data), sort_keys=True, indent=1, ensure_ascii=True) + "\n")
        elif os.path.isfile(src):
            shutil.copyfile(src, dst)
        else:
            print(f"golden: {label}: {name} is not a plain file", file=sys.stderr)
            bad = 1
sys.exit(bad)
PY
}

# run_set OUTDIR: run every golden run, outputs into OUTDIR. Returns 1 if a run failed.
run_set() {
    local out=$1 scratch failed=0 t0 t1 total0 line label job args rest rc labels=()
    scratch=$(mktemp -d "${TMPDIR:-/tmp}/golden-run.XXXXXX")
    total0=$(date +%s.%N)
    : >"$out/manifest.txt"
    {
        echo "binary: $BIN"
        echo "sha256: $(sha256sum "$BIN" | cut -d' ' -f1)"
        echo "date:   $(date -u +%Y-%m-%dT%H:%M:%SZ)   host: $(hostname)   cores: $(nproc)"
    } >"$out/info.txt"
    for line in "${RUNS[@]}"; do
        read -r label job rest <<<"$line"
        labels+=("$label")
        # shellcheck disable=SC2206
        args=($rest)
        [[ " $rest " == *" --threads "* ]] || args+=(--threads 2)
        case "$job" in
        render) args+=(--quiet --out out.png --stats out.stats.json) ;;
        light) args+=(--quiet --lit-out out.lit.csv --stats out.stats.json) ;;
        radiosity) args+=(--quiet --patches-csv out.patches.csv --shots-csv out.shots.csv
            --residual-plot out.residual.png --stats out.stats.json) ;;
        esac
        echo "$label: host-sim $job ${args[*]}" >>"$out/manifest.txt"
        mkdir -p "$scratch/$label/w"
        t0=$(date +%s.%N)
        (cd "$scratch/$label/w" && "$BIN" "$job" "${args[@]}" \
            >"$scratch/$label/stdout" 2>"$scratch/$label/stderr")
        rc=$?
        t1=$(date +%s.%N)
        printf '  %-16s %6.2f s%s\n' "$label" "$(echo "$t1 - $t0" | bc)" \
            "$([ $rc -eq 0 ] || echo "   FAILED (exit $rc)")" | tee -a "$out/info.txt" >&2
        if [ $rc -ne 0 ]; then
            failed=1
            tail -5 "$scratch/$label/stderr" | sed 's/^/      /' >&2
            echo "exit status $rc" >>"$scratch/$label/stderr"
        fi
    done
    finish "$scratch" "$out" "${labels[@]}" || failed=1
    printf '  %-16s %6.2f s\n' total "$(echo "$(date +%s.%N) - $total0" | bc)" | tee -a "$out/info.txt" >&2
    rm -rf "${scratch:?}"
    return $failed
}

# threads_check OUTDIR: threads1.* and threads2.* must be identical.
threads_check() {
    local out=$1 bad=0 f g
    for f in "$out"/threads1.*; do
        g=$out/threads2.${f##*/threads1.}
        if [ ! -e "$g" ] || ! cmp -s "$f" "$g"; then
            echo "golden: threads1 and threads2 differ: ${f##*/} vs ${g##*/}" >&2
            bad=1
        fi
    done
    for g in "$out"/threads2.*; do
        [ -e "$out/threads1.${g##*/threads2.}" ] || { echo "golden: only in threads2: ${g##*/}" >&2; bad=1; }
    done
    return $bad
}

START=$(date +%s)
case "$MODE" in
record)
    if [ -e "$DIR" ] && [ -n "$(ls -A "$DIR" 2>/dev/null)" ] && [ ! -e "$DIR/manifest.txt" ]; then
        echo "golden: $DIR exists, is not empty and holds no manifest.txt: not overwriting it" >&2
        exit 2
    fi
    mkdir -p "$DIR" || exit 2
    DIR=$(cd "$DIR" && pwd)
    find "$DIR" -mindepth 1 -maxdepth 1 -type f -delete
    echo "golden: recording with $BIN into $DIR" >&2
    status=0
    run_set "$DIR" || { echo "golden: some runs failed" >&2; status=1; }
    threads_check "$DIR" || status=1
    echo "golden: recorded $(ls "$DIR" | wc -l) files in $(($(date +%s) - START)) s$([ $status -eq 0 ] || echo ' (WITH ERRORS)')" >&2
    exit $status
    ;;
compare)
    [ -f "$DIR/manifest.txt" ] || { echo "golden: $DIR holds no manifest.txt (record first)" >&2; exit 2; }
    DIR=$(cd "$DIR" && pwd)
    NEW=$(mktemp -d "${TMPDIR:-/tmp}/golden-compare.XXXXXX")
    echo "golden: running $BIN into $NEW, comparing with $DIR" >&2
    status=0
    run_set "$NEW" || { echo "golden: some runs failed" >&2; status=1; }
    threads_check "$NEW" || status=1
    ndiff=0
    while read -r f; do
        if [ ! -e "$NEW/$f" ]; then
            echo "MISSING  $f   (in golden, not written now)"; ndiff=$((ndiff + 1))
        elif [ ! -e "$DIR/$f" ]; then
            echo "EXTRA    $f   (written now, not in golden)"; ndiff=$((ndiff + 1))
        elif ! cmp -s "$DIR/$f" "$NEW/$f"; then
            echo "DIFFERS  $f   ($(cmp "$DIR/$f" "$NEW/$f" 2>&1 | head -1 | sed 's/^.*differ: //'))"
            ndiff=$((ndiff + 1))
            case "$f" in *.txt | *.json | *.csv)
                diff "$DIR/$f" "$NEW/$f" | head -8 | sed 's/^/           /' ;;
            esac
        fi
    done < <( (cd "$DIR" && ls -A; cd "$NEW" && ls -A) | grep -vx 'info.txt' | sort -u)
    if [ $ndiff -ne 0 ] || [ $status -ne 0 ]; then
        echo "golden: FAIL: $ndiff file(s) differ$([ $status -eq 0 ] || echo ', and runs failed or threads1/threads2 differ'); new outputs kept in $NEW" >&2
        exit 1
    fi
    rm -rf "${NEW:?}"
    echo "golden: OK: $(($(ls -A "$DIR" | wc -l) - 1)) files identical ($(($(date +%s) - START)) s)" >&2
    exit 0
    ;;
esac
