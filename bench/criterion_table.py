#!/usr/bin/env python3
"""Print the medians of the last `cargo bench` run as a Markdown table.

Reads $CARGO_TARGET_DIR/criterion/**/new/{benchmark,estimates}.json (criterion's own output;
target/ when CARGO_TARGET_DIR is unset) and prints one row per benchmark: median, median
absolute deviation, and, when the benchmark declares a throughput of N elements, the median per
element. Usage:
    python3 bench/criterion_table.py [--since FILE] [--pivot] [PREFIX ...]
PREFIX: only benchmarks whose id starts so. --since FILE: only benchmarks measured after FILE
was last modified (what one `cargo bench` run measured: bench/criterion.sh). --pivot: ids
GROUP/FUNCTION/INPUT as one row per INPUT and one column per FUNCTION (median, ± MAD).
"""
import glob
import json
import os
import sys


def fmt(ns):
    for unit, scale in (("s", 1e9), ("ms", 1e6), ("µs", 1e3)):
        if ns >= scale:
            return f"{ns / scale:.3g} {unit}"
    return f"{ns:.3g} ns"


def main():
    args = sys.argv[1:]
    since, pivot = None, False
    while args and args[0].startswith("--"):
        if args[0] == "--since":
            since = os.path.getmtime(args[1])
            args = args[2:]
        elif args[0] == "--pivot":
            pivot = True
            args = args[1:]
        else:
            sys.exit(f"criterion_table.py: unknown option {args[0]}")
    target = os.environ.get("CARGO_TARGET_DIR") or os.path.join(os.path.dirname(__file__), "..", "target")
    root = os.path.join(target, "criterion")
    prefixes = args
    rows = []
    for path in glob.glob(os.path.join(root, "**", "new", "benchmark.json"), recursive=True):
        b = json.load(open(path))
        if prefixes and not any(b["full_id"].startswith(p) for p in prefixes):
            continue
        est = os.path.join(os.path.dirname(path), "estimates.json")
        if since is not None and os.path.getmtime(est) < since:
            continue
        e = json.load(open(est))
        med = e["median"]["point_estimate"]
        mad = e["median_abs_dev"]["point_estimate"]
        thr = b.get("throughput") or {}
        per = f"{fmt(med / thr['Elements'])}" if "Elements" in thr and thr["Elements"] else ""
        rows.append((b["full_id"], fmt(med), fmt(mad), per))
    if pivot:
        funcs = sorted({r[0].split("/")[1] for r in rows})
        inputs = sorted({r[0].split("/", 2)[2] for r in rows})
        at = {(r[0].split("/")[1], r[0].split("/", 2)[2]): r for r in rows}
        print("| input | " + " | ".join(f"`{f}`" for f in funcs) + " |")
        print("|---|" + "---|" * len(funcs))
        for i in inputs:
            cells = [f"{at[f, i][1]} ± {at[f, i][2]}" if (f, i) in at else "–" for f in funcs]
            print(f"| {i} | " + " | ".join(cells) + " |")
        return
    print("| benchmark | median | MAD | per element |")
    print("|---|---|---|---|")
    for r in sorted(rows):
        print(f"| `{r[0]}` | " + " | ".join(r[1:]) + " |")


if __name__ == "__main__":
    main()
