# Cell-by-cell comparison of `adaptive` against every other equal-budget method
# (`full-res-60hz` left out; with NOABL=1 in the environment, the adaptive-* ablations too).
# usage: cells.py NAME=FILE ...   FILE: a Table 1 summary.json (with "animations"), or
# eval summary.json files joined by '+' (their results are pooled).
import json, os, sys
EXCLUDE = {"full-res-60hz"}
def runs(path):
    if "+" in path:
        res = []
        for p in path.split("+"):
            res += json.load(open(p))["results"]
        yield None, res
        return
    d = json.load(open(path))
    if "animations" in d:
        for a in d["animations"]:
            yield a["name"], a["summary"]["results"]
    else:
        yield None, d["results"]
rows = []
for arg in sys.argv[1:]:
    label, path = arg.split("=", 1)
    for name, res in runs(path):
        by = {}
        for r in res:
            by.setdefault(r["rate"], {})[r["method"]] = r
        for rate in sorted(by):
            m = by[rate]
            a = m["adaptive"]
            others = {k: v for k, v in m.items() if k != "adaptive" and k not in EXCLUDE and not (os.environ.get("NOABL") and k.startswith("adaptive"))}
            br = min(others, key=lambda k: others[k]["rms_mean"])
            bf = min(others, key=lambda k: others[k]["flip_mean"])
            tf = m.get("traditional-frameless")
            cell = f"{name or label} {rate/1000:.0f}K"
            def mark(x, y):
                return "✓" if x < y else f"✗ +{(x / y - 1) * 100:.1f}%"
            rms = f"{a['rms_mean']:.2f} vs {br} {others[br]['rms_mean']:.2f} {mark(a['rms_mean'], others[br]['rms_mean'])}"
            fl = f"{a['flip_mean']:.4f} vs {bf} {others[bf]['flip_mean']:.4f} {mark(a['flip_mean'], others[bf]['flip_mean'])}"
            ratio = f"{a['rms_mean'] / tf['rms_mean']:.3f}" if tf else "—"
            rows.append(f"| {cell} | {rms} | {fl} | {ratio} |")
print("| cell | RMS: adaptive vs best other | FLIP: adaptive vs best other | adaptive ÷ TF RMS |")
print("|---|---|---|---|")
print("\n".join(rows))
