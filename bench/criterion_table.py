#!/usr/bin/env python3
"""Print the medians of the last `cargo bench` run as a Markdown table.

Reads target/criterion/**/new/{benchmark,estimates}.json (criterion's own output) and prints
one row per benchmark: median, median absolute deviation, and, when the benchmark declares a
throughput of N elements, the median per element. Usage:
    python3 bench/criterion_table.py [PREFIX ...]     (only benchmarks whose id starts so)
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
    root = os.path.join(os.path.dirname(__file__), "..", "target", "criterion")
    prefixes = sys.argv[1:]
    rows = []
    for path in glob.glob(os.path.join(root, "**", "new", "benchmark.json"), recursive=True):
        b = json.load(open(path))
        if prefixes and not any(b["full_id"].startswith(p) for p in prefixes):
            continue
        e = json.load(open(os.path.join(os.path.dirname(path), "estimates.json")))
        med = e["median"]["point_estimate"]
        mad = e["median_abs_dev"]["point_estimate"]
        thr = b.get("throughput") or {}
        per = f"{fmt(med / thr['Elements'])}" if "Elements" in thr and thr["Elements"] else ""
        rows.append((b["full_id"], fmt(med), fmt(mad), per))
    print("| benchmark | median | MAD | median per element |")
    print("|---|---|---|---|")
    for r in sorted(rows):
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
