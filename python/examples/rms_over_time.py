# %% [markdown]
# # RMS error over time, from Python
#
# Evaluates three methods on the built-in `toycar` scene at one sample rate, then plots
# each method's RMS error (0–255 units) against the ideal image at every refresh. Runs
# as a script (`python rms_over_time.py [OUT.png]`) or cell by cell in a notebook
# (Jupyter, VS Code: the `# %%` markers split it). The plot needs matplotlib; without
# it the table is printed instead.

# %%
import sys

import numpy as np

import frameless

scene = frameless.Scene.load("toycar")
scene

# %% [markdown]
# A still image: display values as an H×W×3 float32 array (`frameless.to_display` gives
# the 8-bit image the command line writes to PNG).

# %%
still = scene.still(0.5, size=(128, 96), spp=4)
print("still:", still.shape, still.dtype, f"mean {still.mean():.3f}")

# %% [markdown]
# The evaluation: `frameless eval --method traditional-frameless,taa,adaptive --rate
# 400k --size 128x96 --duration 0.5`, in this process.

# %%
methods = ["traditional-frameless", "taa", "adaptive"]
ev = frameless.evaluate(
    scene, methods=methods, rates=["400k"], size=(128, 96), duration=0.5, warmup=0.5
)
for row in ev.results:
    print(f"{row['method']:>22}: RMS {row['rms_mean']:6.2f}  FLIP {row['flip_mean']:.3f}")

# %%
try:
    import matplotlib.pyplot as plt

    have_matplotlib = True
except ImportError:
    have_matplotlib = False
    print("matplotlib is not installed: no plot")

if have_matplotlib:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for m in methods:
        pick = ev.frames["method"] == m
        ax.plot(ev.frames["time"][pick], ev.frames["rms"][pick], label=m)
    ax.set_xlabel("scene time (s)")
    ax.set_ylabel("RMS error (0–255)")
    ax.set_title("toycar at 400K samples/s")
    ax.legend()
    fig.tight_layout()
    out = sys.argv[1] if __name__ == "__main__" and len(sys.argv) > 1 else "rms_over_time.png"
    fig.savefig(out, dpi=100)
    print("plot:", out)

# %% [markdown]
# With pandas installed the same table is a DataFrame: `ev.frames_df`.

# %%
if ev.frames_df is not None:
    print(ev.frames_df.groupby("method")["rms"].describe()[["mean", "min", "max"]])
else:
    print({m: float(np.mean(ev.frames["rms"][ev.frames["method"] == m])) for m in methods})
