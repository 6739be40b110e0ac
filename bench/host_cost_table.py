#!/usr/bin/env python3
"""Helpers of bench/host_cost.sh (standard library only).

  host_cost_table.py fields STATS.json
      One comma-separated line: job_wall_s,light_s,beams,cycles,messages (blank where the
      job's stats have no such key). render: light.{wall_seconds,beams_processed,cycles,
      messages}; light: beams, cycles and messages at the top level, no light seconds of its
      own; radiosity: no light seconds and no beam count in its stats, cycles and messages at
      the top level.
  host_cost_table.py same REF.json OTHER.json
      Compare the simulated counts of two stats files: every key named like *wall*,
      *seconds* or peak_rss* is dropped (at any depth), the rest must be equal. Prints the
      differing keys and exits 1 if they are not.
  host_cost_table.py cgrefs CACHEGRIND.out
      The total instruction count (I refs) of a cachegrind output file.
  host_cost_table.py table CSV HEADER_FILE
      The markdown summary of host_cost.sh's CSV, one line per row, after the header lines.
"""
import csv
import json
import os
import statistics
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def get(d, *keys):
    for k in keys:
        if not isinstance(d, dict) or d.get(k) is None:
            return None
        d = d[k]
    return d


def fmt(v):
    if v is None:
        return ""
    return f"{v:.3f}" if isinstance(v, float) else str(v)


def fields(path):
    s = load(path)
    if isinstance(s.get("light"), dict):  # render
        vals = [s.get("wall_seconds"), get(s, "light", "wall_seconds"),
                get(s, "light", "beams_processed"), get(s, "light", "cycles"),
                get(s, "light", "messages")]
    else:  # light, radiosity (and anything else with top-level counts)
        vals = [s.get("wall_seconds"), s.get("light_seconds"), s.get("beams_processed"),
                s.get("cycles"), s.get("messages")]
    print(",".join(fmt(v) for v in vals))


def volatile(key):
    k = key.lower()
    return "wall" in k or "seconds" in k or k.startswith("peak_rss")


def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if not volatile(k)}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v


def flatten(v, prefix=""):
    if isinstance(v, dict):
        out = {}
        for k, x in v.items():
            out.update(flatten(x, f"{prefix}.{k}" if prefix else k))
        return out
    if isinstance(v, list):
        out = {}
        for i, x in enumerate(v):
            out.update(flatten(x, f"{prefix}[{i}]"))
        return out
    return {prefix: v}


def same(ref_path, other_path):
    a, b = strip(load(ref_path)), strip(load(other_path))
    if a == b:
        return 0
    fa, fb = flatten(a), flatten(b)
    keys = sorted(set(fa) | set(fb))
    if os.environ.get("NEW_KEYS") == "ignore":
        # A stats field one build writes and the other does not (added between them) is a change
        # of the report, not of the simulation: named, not compared.
        for k in keys:
            if (k in fa) != (k in fb):
                print(f"host_cost: note: {k} only in {'the reference' if k in fa else 'this run'}", file=sys.stderr)
        keys = [k for k in keys if k in fa and k in fb]
    diffs = [k for k in keys if fa.get(k, "<missing>") != fb.get(k, "<missing>")]
    if not diffs:
        return 0
    for k in diffs[:40]:
        print(f"    {k}: {fa.get(k, '<missing>')} != {fb.get(k, '<missing>')}")
    if len(diffs) > 40:
        print(f"    … and {len(diffs) - 40} more keys")
    return 1


def cgrefs(path):
    with open(path) as f:
        for line in f:
            if line.startswith("summary:"):
                print(line.split()[1])
                return 0
    print(f"no 'summary:' line in {path}", file=sys.stderr)
    return 1


def num(x):
    try:
        return float(x)
    except (TypeError, ValueError):
        return None


def med(rows, col):
    v = [num(r[col]) for r in rows if num(r[col]) is not None]
    return statistics.median(v) if v else None


def f(v, digits=2):
    return "—" if v is None else f"{v:.{digits}f}"


def si(v):
    if v is None:
        return "—"
    for div, unit in ((1e9, " G"), (1e6, " M"), (1e3, " k")):
        if abs(v) >= div:
            return f"{v / div:.3g}{unit}"
    return f"{v:.0f}"


def arrow(a, b, digits=1):
    if a is None and b is None:
        return "—"
    return f"{f(a, digits)} → {f(b, digits)}"


def table(csv_path, header_path):
    with open(csv_path) as fh:
        runs = list(csv.DictReader(fh))
    with open(header_path) as fh:
        print(fh.read().rstrip("\n"))
    print()
    print("| row | threads | reps | base wall s | new wall s | new/base (paired) | light s base → new "
          "| beams | ns/beam base → new | instr/beam base → new | peak RSS MiB base → new | cycles |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    order = list(dict.fromkeys(r["row"] for r in runs))
    for row in order:
        rr = [r for r in runs if r["row"] == row]
        timed = {b: [r for r in rr if r["binary"] == b and r["rep"] != "cg"] for b in ("base", "new")}
        cg = {b: [r for r in rr if r["binary"] == b and r["rep"] == "cg"] for b in ("base", "new")}
        wb, wn = med(timed["base"], "wall_s"), med(timed["new"], "wall_s")
        ratio = f"{wn / wb:.3f}" if wb and wn else "—"
        pairs = [num(n["wall_s"]) / num(b["wall_s"]) for b in timed["base"] for n in timed["new"]
                 if b["rep"] == n["rep"] and num(b["wall_s"]) and num(n["wall_s"])]
        if pairs:
            ratio += f" ({statistics.median(pairs):.3f})"
        any_run = (timed["base"] or timed["new"] or cg["base"] or cg["new"])[0]
        beams = num(any_run["beams"])
        # instructions: per beam where the job counts beams, else per message (radiosity),
        # with the command where the cachegrind run is not the row's own (--threads 1 aside)
        ib = [num(cg[b][0]["instr_per_beam"]) if cg[b] else None for b in ("base", "new")]
        im = [num(cg[b][0]["instr_per_msg"]) if cg[b] else None for b in ("base", "new")]
        if ib != [None, None]:
            instr = f"{f(ib[0], 0)} → {f(ib[1], 0)}"
        elif im != [None, None]:
            instr = f"{f(im[0], 0)} → {f(im[1], 0)} per msg"
        else:
            instr = "—"
        if cg["base"] or cg["new"]:
            cg_args = (cg["base"] or cg["new"])[0]["args"]
            if cg_args.replace(" --threads 1", "") != any_run["args"].replace(" --threads 1", ""):
                instr += f" (`{cg_args}`)"
        # core time: per beam where the job counts beams, else per message (radiosity)
        if beams is None and num(any_run["messages"]) is not None:
            nspb = arrow(med(timed["base"], "ns_per_msg"), med(timed["new"], "ns_per_msg"), 0) + " per msg"
        else:
            nspb = arrow(med(timed["base"], "ns_per_beam"), med(timed["new"], "ns_per_beam"), 0)
        reps = max(len(timed["base"]), len(timed["new"]))
        print(f"| {row} | {any_run['threads']} | {reps} | {f(wb)} | {f(wn)} | {ratio} | "
              f"{arrow(med(timed['base'], 'light_s'), med(timed['new'], 'light_s'), 2)} | "
              f"{si(beams)} | {nspb} | "
              f"{instr} | {arrow(med(timed['base'], 'peak_rss_mib'), med(timed['new'], 'peak_rss_mib'), 0)} | "
              f"{any_run['cycles'] or '—'} |")
    print()
    print("Medians over the reps; new/base is the ratio of the median walls, (paired) the median of "
          "the per-rep new/base ratios. ns/beam = (user + sys CPU s) × 1e9 / beams processed. "
          "instr/beam: cachegrind I refs (whole process, --threads 1) / beams processed. Jobs without a "
          "beam count (radiosity) give both per simulated message.")
    return 0


def main(argv):
    cmd, args = argv[1], argv[2:]
    if cmd == "fields":
        fields(args[0])
        return 0
    if cmd == "same":
        return same(args[0], args[1])
    if cmd == "cgrefs":
        return cgrefs(args[0])
    if cmd == "table":
        return table(args[0], args[1])
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
