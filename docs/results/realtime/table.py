"""Print the Markdown tables of README.md from the stats.json files of run.sh."""
import json, os, sys

out = sys.argv[1]

def load(name):
    with open(os.path.join(out, name, "stats.json")) as f:
        return json.load(f)

def share(s):
    m = s.get("machine_share")
    return "?" if m is None else f"{m*100:.0f}%"

print("| sampling threads | samples/s | sampling (thread-ms per image) | reconstruction (ms per image) | images/s (FPS) | refreshes/s | late refreshes | mean age (ms) | machine share |")
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for n in (1, 2, 4, 8):
    s = load(f"kitchen_t{n}")
    p, d = s["pipeline"], s["display"]
    print(f"| {n} | {s['samples_per_s']/1e3:.0f}K | {p['sampling_ms_per_image']:.1f} | "
          f"{p['reconstruct_ms_mean']:.1f} (p95 {p['reconstruct_ms_p95']:.1f}) | {s['display_fps']:.1f} | "
          f"{d['present_hz']:.1f} | {d['late_refreshes']} | {p['mean_age_s']*1e3:.0f} | {share(s)} |")
print()
def placed(p):
    # Adaptive only: samples placed per image of the ring's capacity.
    if not p.get("ring_capacity"):
        return "–"
    return f"{p.get('placed_mean', 0)/1e3:.0f}K of {p['ring_capacity']/1e3:.0f}K"

def ms(v):
    return "?" if v is None else f"{v*1e3:.0f}"

print("| scene | method | samples/s | images/s (FPS) | refresh target / achieved (Hz) | late refreshes | reconstruction (ms) | samples placed per image | age p50 / p95 (ms) | camera step: view / half new (ms) | sampling threads | machine share |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for scene, label in (("kitchen", "kitchen 256×256"), ("toycar640", "toycar 640×480")):
    for m in ("adaptive", "adaptive-nobudget", "traditional-frameless", "framed", "late-warp", "taa", "taa-warp"):
        if not os.path.exists(os.path.join(out, f"{scene}_{m}", "stats.json")):
            continue
        s = load(f"{scene}_{m}")
        p, d = s["pipeline"], s["display"]
        step = s.get("camera_step") or {}
        view = step.get("view_ms")
        half = step.get("half_new_ms")
        steps = "?" if view is None else f"{view:.0f} / {half:.0f}" if half is not None else f"{view:.0f} / ?"
        print(f"| {label} | {m} | {s['samples_per_s']/1e6:.2f} M | {s['display_fps']:.1f} | "
              f"{d['refresh_hz']:.0f} / {d['present_hz']:.1f} | {d['late_refreshes']} | "
              f"{p['reconstruct_ms_mean']:.1f} | {placed(p)} | {ms(p.get('age_p50_s'))} / {ms(p.get('age_p95_s'))} | "
              f"{steps} | {p['sampling_threads']} | {share(s)} |")
