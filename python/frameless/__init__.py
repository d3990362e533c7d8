"""Adaptive frameless rendering from Python, images as numpy arrays.

The nouns, names and defaults are the ``frameless`` command line's::

    import frameless
    scene = frameless.Scene.load("toycar")
    img = scene.still(0.5, spp=16)                         # H×W×3 float32 display values
    frameless.write_image("still.png", img)                # or .exr, in linear light
    ev = frameless.evaluate(scene, methods=["adaptive", "taa"], rates=["400k"])
    ev.results                                             # as summary.json has them
    ev.frames["rms"]                                       # numpy columns of frames.csv
    for t, img in frameless.render(scene, "adaptive", "400k", duration=0.25): ...
    frameless.metrics.compare(reference, img)              # RMS, PSNR, FLIP of any two

Long work releases the GIL, stops on Ctrl-C (KeyboardInterrupt) and shows a tqdm
progress bar where tqdm is installed. A bad setting raises ValueError naming the
keyword. The command line itself is the ``frameless`` command (and ``python -m
frameless``). See docs/python.md in the repository.
"""

from . import metrics
from ._api import (
    DEFAULT_METHODS,
    DEFAULT_RATES,
    Evaluation,
    Render,
    Scene,
    evaluate,
    live,
    read_image,
    render,
    scenes,
    write_image,
)
from ._frameless import __version__, to_display, to_linear

__all__ = [
    "Scene",
    "Evaluation",
    "Render",
    "evaluate",
    "live",
    "render",
    "scenes",
    "read_image",
    "write_image",
    "to_display",
    "to_linear",
    "metrics",
    "DEFAULT_METHODS",
    "DEFAULT_RATES",
]
