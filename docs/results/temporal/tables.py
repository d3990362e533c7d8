"""Tables of docs/results/temporal/README.md from the summary.json files run.sh keeps.

Usage: python3 docs/results/temporal/tables.py docs/results/temporal > tables.md

Per window and rate: every equal-budget method (a method whose effective rate is the
column's: full-res-60hz is left out) with its mean RMS, FLIP, sustained and transient
error and instability, and its rank by each; then, per cell, the best method by each
score and Kendall's tau between the RMS ranking and each other one.
"""

import json
import os
import sys
from itertools import combinations

WINDOWS = [
    ("interactive", "table1_400k/interactive", [400e3]),
    ("bart", "table1_400k/bart", [400e3]),
    ("toycar", "table1_400k/toycar", [400e3]),
    ("still", "table1_400k/still", [400e3]),
    ("m5", "m5", [100e3, 400e3]),
    ("m4", "m4", [100e3, 400e3]),
    ("gl", "gl", [100e3, 400e3]),
    ("demo", "demo", [100e3, 400e3]),
    ("room", "room", [100e3, 400e3]),
    ("m3", "m3", [100e3, 400e3]),
]

SCORES = [
    ("RMS", "rms_mean", 2),
    ("FLIP", "flip_mean", 4),
    ("sustained", "sustained_mean", 2),
    ("transient", "transient_mean", 2),
    ("instability", "instability_mean", 2),
]


def label(rate):
    return f"{rate / 1e3:.0f}K"


def ranks(rows, key):
    order = sorted(rows, key=lambda r: r[key])
    return {r["method"]: i + 1 for i, r in enumerate(order)}


def kendall(a, b):
    """Kendall's tau-a between two rankings of the same methods."""
    ms = list(a)
    c = d = 0
    for x, y in combinations(ms, 2):
        s = (a[x] - a[y]) * (b[x] - b[y])
        c += s > 0
        d += s < 0
    n = len(ms) * (len(ms) - 1) / 2
    return (c - d) / n


def main(here):
    cells = []
    out = []
    for name, folder, rates in WINDOWS:
        path = os.path.join(here, folder, "summary.json")
        if not os.path.exists(path):
            print(f"<!-- {path} missing -->")
            continue
        s = json.load(open(path))
        for rate in rates:
            rows = [
                r
                for r in s["results"]
                if r["rate"] == rate and r["effective_rate"] == rate
                and r.get("sustained_mean") is not None
            ]
            if not rows:
                continue
            rk = {key: ranks(rows, key) for _, key, _ in SCORES}
            out.append(f"### {name} {label(rate)} (t = {s['start']}–{s['start'] + s['duration']} s)\n")
            out.append("| method | " + " | ".join(f"{t} (rank)" for t, _, _ in SCORES)
                       + " | sustained ÷ transient |")
            out.append("|---|" + "---:|" * (len(SCORES) + 1))
            for r in sorted(rows, key=lambda r: r["rms_mean"]):
                m = r["method"]
                vals = " | ".join(f"{r[k]:.{p}f} ({rk[k][m]})" for _, k, p in SCORES)
                # A display that never changes has no transient error: no ratio.
                t = r["transient_mean"]
                ratio = f"{r['sustained_mean'] / t:.2f}" if t >= 0.005 else "–"
                out.append(f"| {m} | {vals} | {ratio} |")
            out.append("")
            cells.append((name, rate, rows, rk))
    # The summary across cells.
    print("## Best method per cell, and agreement with the RMS ranking\n")
    print("Kendall's tau of each score's ranking against RMS's (1: the same order).\n")
    print("| cell | best RMS | best FLIP | best sustained | best transient | lowest instability "
          "| τ FLIP | τ sustained | τ transient | τ instability |")
    print("|---|---|---|---|---|---|---:|---:|---:|---:|")
    for name, rate, rows, rk in cells:
        best = {k: min(rows, key=lambda r: r[k])["method"] for _, k, _ in SCORES}
        taus = [kendall(rk["rms_mean"], rk[k]) for _, k, _ in SCORES[1:]]
        print(f"| {name} {label(rate)} | " + " | ".join(best[k] for _, k, _ in SCORES)
              + " | " + " | ".join(f"{t:.2f}" for t in taus) + " |")
    print("\n## Every cell\n")
    print("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__)))
