#!/usr/bin/env python3
"""Print the compact tables of docs/results/live/README.md from each case's
summary.json: per method the median RMS, FLIP and age at scan-out, and the live
figures, with the range over the runs where it matters."""
import json
import pathlib
import sys

here = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent)
for case in sorted(p for p in here.iterdir() if (p / "summary.json").is_file()):
    s = json.loads((case / "summary.json").read_text())
    print(f"### {case.name}: {s['width']}x{s['height']} at {s['refresh_hz']:g} Hz, "
          f"t = {s['start']:g} s + {s['seconds']:g} s, {s['repeat']} runs each\n")
    print("| method | RMS | FLIP | age at scan-out (ms) | samples/s | new images/s "
          "| machine share | warnings |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    best_rms = min(r["median"]["rms"] for r in s["results"])
    best_flip = min(r["median"]["flip"] for r in s["results"])
    for r in s["results"]:
        med, lo, hi = r["median"], r["min"], r["max"]
        rms = f"{med['rms']:.2f} ({lo['rms']:.2f}–{hi['rms']:.2f})"
        flip = f"{med['flip']:.4f} ({lo['flip']:.4f}–{hi['flip']:.4f})"
        if med["rms"] == best_rms:
            rms = f"**{rms}**"
        if med["flip"] == best_flip:
            flip = f"**{flip}**"
        age = "–" if med.get("age_s") is None else f"{1e3 * med['age_s']:.0f}"
        share = "–" if med.get("machine_share") is None else f"{med['machine_share']:.2f}"
        print(f"| {r['method']} | {rms} | {flip} | {age} | {med['samples_per_s'] / 1e6:.2f} M "
              f"| {med['images_per_s']:.1f} | {share} | {r['warnings']} of {r['runs']} |")
    print()
