#!/usr/bin/env python3
"""The device run's live scaling table from its `<step>.summary.json` files (or
`<step>/summary.json` folders): per case, adaptive against traditional frameless, with
adaptive's image build and its three largest steps. Usage: table.py DIR"""
import json
import pathlib
import sys

here = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".")
cases = sorted(here.glob("live_*.summary.json")) + sorted(here.glob("live_*/summary.json"))
print("| case | size | Hz | method | new images/s | samples/s (M) | RMS / FLIP "
      "| build ms mean / p95 (threads) | placed per image | sampling busy | largest steps (ms) |")
print("|---|---|---:|---|---:|---:|---|---|---:|---:|---|")
for path in cases:
    s = json.loads(path.read_text())
    name = path.name.removesuffix(".summary.json") if path.name != "summary.json" else path.parent.name
    for r in s["runs"]:
        p, sc = r["pipeline"], r["scores"]
        steps = sorted(p.get("pass_ms", {}).items(), key=lambda kv: -kv[1])[:3]
        steps = ", ".join(f"{k} {v:.1f}" for k, v in steps if v > 0) or "–"
        placed = p.get("placed_mean")
        placed = "–" if placed is None else f"{placed / 1e3:.0f}K"
        print(f"| {name} | {s['width']}×{s['height']} | {s['refresh_hz']:g} | {r['method']} "
              f"| {sc['images_per_s']:.1f} | {sc['samples_per_s'] / 1e6:.2f} "
              f"| {sc['rms']:.2f} / {sc['flip']:.4f} "
              f"| {p['reconstruct_ms_mean']:.1f} / {p['reconstruct_ms_p95']:.1f} ({p['recon_threads']}) "
              f"| {placed} | {p['sampling_busy_share']:.2f} | {steps} |")
