"""Markdown tables of bench/host_phases.sh: light-phase seconds by phase (medians, 1 and 2
threads, the 2-thread speed-up), and the cachegrind instructions of one render split by concern.

Usage: host_phases_table.py CSV CG_TXT CG_STATS_JSON COMMAND REV   (CG_TXT "" for none)
"""
import csv
import datetime
import json
import platform
import re
import statistics
import sys

PHASES = ["setup", "emit", "step", "gather", "links", "pop", "next", "tally"]
PARALLEL = {"step", "links"}

# Concerns by source file (the file a line of inlined code comes from), or by function name
# for library code; first match wins.
CONCERNS = [
    ("frustum test (cell, and the host's table of its commonest answer)", r"occupancy|shortcut"),
    ("exact occluders (cell, and the host's per-source tables)",
     r"occluder|/lit\.rs|lit::|receiver|triangles?\.rs|occluders\.rs|ExactVisit|Seen"),
    ("beam split (cell)", r"beam\.rs|bounds\.rs|split|ceil_div"),
    ("fate and routing (cell)", r"fate"),
    ("step, FIFO, output buffers, accept (cell)", r"light/mod\.rs|out\.rs|msg\.rs|LightCell|activity|heapless"),
    ("engine: pieces, offers, links, lists (host)", r"diffuse|tiles|pieces|links|call_mut|mem(move|cpy|set)|rayon|crossbeam"),
]
OTHER = "other: loading, shading, runtime"


def medians(path):
    rows = {}
    for r in csv.DictReader(open(path)):
        rows.setdefault((r["row"], int(r["threads"])), []).append(r)
    med = {}
    for key, rs in rows.items():
        med[key] = {k: statistics.median(float(r[k]) for r in rs) for k in ["light_s", "beams"] + PHASES}
        med[key]["n"] = len(rs)
    return med


def phase_table(med):
    out = ["| row | threads | light s | " + " | ".join(PHASES) + " | serial share |",
           "|---|---|---|" + "---|" * len(PHASES) + "---|"]
    for (row, t), m in med.items():
        serial = sum(m[p] for p in PHASES if p not in PARALLEL) / max(m["light_s"], 1e-9)
        cells = [f"{m[p]:.3f}" for p in PHASES]
        out.append(f"| {row} | {t} | {m['light_s']:.2f} | " + " | ".join(cells) + f" | {100 * serial:.1f} % |")
    out.append("")
    out.append("| row | 2-thread speed-up: light | step | links |")
    out.append("|---|---|---|---|")
    for row in dict.fromkeys(r for r, _ in med):
        a, b = med.get((row, 1)), med.get((row, 2))
        if a and b:
            r = lambda k: a[k] / max(b[k], 1e-9)
            out.append(f"| {row} | {r('light_s'):.2f}× | {r('step'):.2f}× | {r('links'):.2f}× |")
    return out


def concern_table(cg_txt, stats):
    tot, cats = 0, {}
    for line in open(cg_txt):
        m = re.match(r"\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*)", line)
        if not m:
            continue
        n, name = int(m.group(1).replace(",", "")), m.group(2)
        if name.strip() == "PROGRAM TOTALS":
            tot = n
            continue
        file, _, fn = name.partition(":")
        library = file.startswith(("/rustc", "./")) or "registry" in file
        key = fn if library else file
        cat = next((c for c, r in CONCERNS if re.search(r, key)), OTHER)
        cats[cat] = cats.get(cat, 0) + n
    beams = json.load(open(stats))["light"]["beams_processed"]
    out = [f"`render --n 128 --threads 1` (Cornell through its camera), {tot / 1e9:.2f} G instructions, "
           f"{grouped(beams)} processed beams, {grouped(tot / beams)} per beam:",
           "", "| concern | instructions | share | per beam |", "|---|---|---|---|"]
    for c in [c for c, _ in CONCERNS] + [OTHER]:
        v = cats.get(c, 0)
        out.append(f"| {c} | {grouped(v / 1e6)} M | {100 * v / tot:.1f} % | {grouped(v / beams)} |")
    return out


def grouped(x):
    """`x` rounded, thousands separated by spaces (as BENCHMARKS writes numbers)."""
    return f"{round(x):,}".replace(",", " ")


def main():
    csv_path, cg_txt, cg_stats, command, rev = sys.argv[1:6]
    machine = f"{platform.machine()}, {__import__('os').cpu_count()} CPUs"
    date = datetime.date.today().isoformat()
    print(f"Command: `{command}`, commit {rev}, {machine}, {date}.")
    print()
    print("\n".join(phase_table(medians(csv_path))))
    if cg_txt:
        print()
        print("\n".join(concern_table(cg_txt, cg_stats)))


if __name__ == "__main__":
    main()
