"""Summarise bench/thesis-timing.sh's CSVs: every published §4.4.3 point beside ours under each
timing, with ratios; the share within ±20 %; fitted growth exponents; the "large enough" sweep."""
import csv, math, sys
from collections import defaultdict

out = sys.argv[1]


def rows(name):
    return list(csv.DictReader(open(f"{out}/{name}.csv")))


def slope(pts):
    xs = [math.log(n) for n, _ in pts]
    ys = [math.log(t) for _, t in pts]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


# (column label, csv, timing name)
cols = [("rc2, centre (today)", "published-centre", "rc2"),
        ("rc2, origin", "published-origin", "rc2"),
        ("thesis timing, origin", "published-origin", "thesis")]
t = defaultdict(dict)
published = {}
for label, f, timing in cols:
    for r in rows(f):
        if r["timing"] == timing:
            key = (int(r["n"]), int(r["fa"]))
            t[label][key] = int(r["cycles"])
            published[key] = int(r["thesis_t"])
keys = sorted(published)

print("| N | FA | published T | " + " | ".join(f"{c[0]} T (ratio)" for c in cols) + " |")
print("|---|---|---|" + "---|" * len(cols))
for k in keys:
    cells = [f"{t[c[0]][k]} ({t[c[0]][k] / published[k]:.2f})" for c in cols]
    print(f"| {k[0]} | {k[1]} | {published[k]} | " + " | ".join(cells) + " |")
print()
print("| timing | points | within ±20 % | within ±10 % | median ratio | worst ratio (N, FA) |")
print("|---|---|---|---|---|---|")
for c in cols:
    ratios = sorted((t[c[0]][k] / published[k], k) for k in keys)
    within = sum(1 for r, _ in ratios if 0.8 <= r <= 1.2)
    within10 = sum(1 for r, _ in ratios if 0.9 <= r <= 1.1)
    worst = max(ratios, key=lambda rk: abs(math.log(rk[0])))
    med = ratios[len(ratios) // 2][0]
    print(f"| {c[0]} | {len(ratios)} | {within} | {within10} | {med:.2f} | {worst[0]:.2f} ({worst[1][0]}, {worst[1][1]}) |")
print()
print("Fitted exponent of T in N (least squares, log–log):")
print()
print("| series | points | published | " + " | ".join(c[0] for c in cols) + " |")
print("|---|---|---|" + "---|" * len(cols))
for name, ks in [("FA = 1, N = 16, 32, 64, 128", [(16, 1), (32, 1), (64, 1), (128, 1)]),
                 ("FA = 1, N = 4…79", [k for k in keys if k[1] == 1 and k[0] <= 79]),
                 ("FA = 16, N = 32, 64, 128", [(32, 16), (64, 16), (128, 16)]),
                 ("FA = 32, N = 32, 64, 128", [(32, 32), (64, 32), (128, 32)])]:
    pub = slope([(k[0], published[k]) for k in ks])
    ours = [slope([(k[0], t[c[0]][k]) for k in ks]) for c in cols]
    print(f"| {name} | {len(ks)} | {pub:.2f} | " + " | ".join(f"{o:.2f}" for o in ours) + " |")
print()

large = rows("large")
print("FIFOs large enough (FA = 64, never full): T and the peak FIFO we measure, beside the "
      "thesis's table (its FA column: the length it lists):")
print()
print("| N | thesis FA | thesis T | thesis timing, origin: peak FIFO | T | ratio | rc2, centre: peak FIFO | T |")
print("|---|---|---|---|---|---|---|---|")
th = {int(r["n"]): r for r in large if r["timing"] == "thesis"}
rc = {int(r["n"]): r for r in rows("large-centre")}
for n in sorted(th):
    r = th[n]
    c = rc.get(n)
    print(f"| {n} | {r['thesis_fa_large']} | {r['thesis_t_large']} | {r['peak_fifo']} | {r['cycles']} | {r['ratio_large']} | {c['peak_fifo'] if c else ''} | {c['cycles'] if c else ''} |")
common = [n for n in sorted(th) if n >= 8 and th[n]["thesis_t_large"]]
pub = [(n, int(th[n]["thesis_t_large"])) for n in common]
ours = [(n, int(th[n]["cycles"])) for n in common]
cen = [(n, int(rc[n]["cycles"])) for n in common if n in rc]
print()
print(f"Exponent over the N ≥ 8 where our FIFO never filled ({common[0]}…{common[-1]}): published {slope(pub):.2f}, "
      f"ours (thesis timing, origin) {slope(ours):.2f}, ours (rc2, centre) {slope(cen):.2f}")
