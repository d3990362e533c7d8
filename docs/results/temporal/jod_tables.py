"""The JOD tables of docs/results/temporal/README.md from jod.sh's folders.

Usage: python3 docs/results/temporal/jod_tables.py docs/results/temporal/jod_1s > jod.md
(or jod_3s > jod_3s.md)

Per animation (the first second of Table 1's window, or all of it in jod_3s, 400K): every method Table 1 runs
with ColorVideoVDP's JOD (higher is better) beside RMS, FLIP and the sustained and
transient errors (lower is better), each with its rank among the equal-budget methods
(full-res-60hz, with ten times the budget, is shown but not ranked); then Kendall's tau
of each per-frame or temporal score's ranking against JOD's.
"""

import json
import os
import sys
from itertools import combinations

ANIMATIONS = ["interactive", "bart", "toycar", "still"]
SCORES = [("RMS", "rms_mean", 2), ("FLIP", "flip_mean", 4),
          ("sustained", "sustained_mean", 2), ("transient", "transient_mean", 2),
          ("instability", "instability_mean", 2)]


def kendall(a, b):
    c = d = 0
    for x, y in combinations(list(a), 2):
        s = (a[x] - a[y]) * (b[x] - b[y])
        c += s > 0
        d += s < 0
    n = len(a) * (len(a) - 1) / 2
    return (c - d) / n


def main(root):
    taus = []
    body = []
    seconds = None
    for a in ANIMATIONS:
        s = json.load(open(os.path.join(root, a, "summary.json")))
        seconds = s["duration"]
        v = json.load(open(os.path.join(root, a, "vdp.json")))
        jod = {(r["method"], r["rate"]): r["jod"] for r in v["results"]}
        rows = [dict(r, jod=jod[(r["method"], r["rate"])]) for r in s["results"]
                if (r["method"], r["rate"]) in jod]
        ranked = [r for r in rows if r["effective_rate"] == r["rate"]]
        rank = {}
        order = sorted(ranked, key=lambda r: -r["jod"])
        rank["jod"] = {r["method"]: i + 1 for i, r in enumerate(order)}
        for _, k, _ in SCORES:
            rank[k] = {r["method"]: i + 1 for i, r in enumerate(sorted(ranked, key=lambda r: r[k]))}
        body.append(f"### {a} 400K, t = {s['start']}–{s['start'] + s['duration']} s "
                    f"(JOD: {v['metric']} {v['version']}, display {v['display']})\n")
        body.append("| method | JOD (rank) | " + " | ".join(f"{t} (rank)" for t, _, _ in SCORES) + " |")
        body.append("|---|---:|" + "---:|" * len(SCORES))
        for r in sorted(rows, key=lambda r: -r["jod"]):
            m = r["method"]
            rk = (lambda k: f" ({rank[k][m]})") if m in rank["jod"] else (lambda k: "")
            cells = " | ".join(f"{r[k]:.{p}f}{rk(k)}" for _, k, p in SCORES)
            body.append(f"| {m} | {r['jod']:.2f}{rk('jod')} | {cells} |")
        body.append("")
        # JOD's rank 1 is the best, as every other score's: the same direction.
        taus.append((a, order[0]["method"], [kendall(rank["jod"], rank[k]) for _, k, _ in SCORES]))
    print(f"| animation 400K ({seconds:g} s) | best JOD | " + " | ".join(f"τ {t}" for t, _, _ in SCORES) + " |")
    print("|---|---|" + "---:|" * len(SCORES))
    for a, best, ts in taus:
        print(f"| {a} | {best} | " + " | ".join(f"{t:.2f}" for t in ts) + " |")
    print()
    print("\n".join(body))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/results/temporal/jod_1s")
