"""ColorVideoVDP beside the per-frame metrics: what a viewer sees over time.

RMS and FLIP score one refresh at a time. ColorVideoVDP (Mantiuk et al., SIGGRAPH
2024; PyPI ``cvvdp``, module ``pycvvdp``) predicts the visible difference between two
*videos* in JOD (10: no visible difference), with a model of the display they are
seen on. This module scores each method's displayed images, every refresh of the
window, against the ideal images of the same refreshes, as 8-bit frames at the
refresh rate. It is the extra ``frameless[vdp]`` (PyTorch, several GB: see
docs/python.md); nothing else in ``frameless`` imports it.

- ``video_jod(test, reference, fps)``: JOD of two ``F×H×W×3`` uint8 videos.
- ``video_jod_parts(test, reference, fps)``: that JOD and, per visual channel of the
  metric (achromatic sustained, red–green, yellow–violet, achromatic transient), the
  JOD the videos would have if they differed in that channel alone.
- ``evaluation_jod(ev, scene, ...)``: a JOD in every result row of an ``evaluate``
  result (``frameless.evaluate(..., video_metric="cvvdp")`` calls it).
- ``python -m frameless.vdp FOLDER --scene S [--camera-path CSV]``: the same for an
  existing ``frameless eval`` output folder, written to ``FOLDER/vdp.json``, which
  ``frameless report FOLDER`` then shows.

The videos are made again with ``frameless.render`` and ``Scene.still`` under the
evaluation's settings (the seed fixes every image), and each frame's RMS is checked
against the evaluation's before a JOD is given, so the JOD is of the images the
evaluation scored.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

#: ColorVideoVDP's display model for the JOD figures (a 24-inch full-HD monitor seen
#: from about 60 cm; ``pycvvdp``'s ``display_models.json`` lists the others).
DEFAULT_DISPLAY = "standard_fhd"

#: Largest difference allowed between a re-rendered frame's RMS and the evaluation's
#: (``frames.csv`` rounds RMS to 4 decimals).
RMS_TOLERANCE = 1e-3

_metrics: Dict[str, Any] = {}


def _cvvdp(display: str):
    """The ColorVideoVDP metric for ``display``, made once per process (its first
    construction is slow)."""
    if display not in _metrics:
        try:
            import pycvvdp
        except ImportError as e:
            raise ImportError(
                "ColorVideoVDP is not installed: pip install 'frameless[vdp]' "
                "(or pip install cvvdp); see docs/python.md"
            ) from e
        _metrics[display] = pycvvdp.cvvdp(display_name=display, quiet=True)
    return _metrics[display]


#: ColorVideoVDP's visual channels of a video, in the order of its per-channel
#: quality (``Q_per_ch``): the achromatic channel's sustained response, the two
#: chromatic channels, and the achromatic channel's transient response.
CHANNELS = ("achromatic_sustained", "red_green", "yellow_violet", "achromatic_transient")


def video_jod(test: np.ndarray, reference: np.ndarray, fps: float,
              display: str = DEFAULT_DISPLAY) -> float:
    """ColorVideoVDP's JOD of the video ``test`` against ``reference``: both
    ``F×H×W×3`` uint8 (8-bit display values, taken as sRGB by the display model),
    ``fps`` frames per second."""
    return video_jod_parts(test, reference, fps, display)["jod"]


def video_jod_parts(test: np.ndarray, reference: np.ndarray, fps: float,
                    display: str = DEFAULT_DISPLAY) -> Dict[str, Any]:
    """``{"jod": J, "parts": {channel: J_c}}``: ColorVideoVDP's JOD of ``test`` against
    ``reference`` (as ``video_jod``), and for each of ``CHANNELS`` the JOD pooled from
    that channel's quality alone, the others' set to no difference. ``J_c`` is at least
    ``J``; the channel whose ``J_c`` is lowest is where most of the visible difference
    is (lag in the sustained response, flicker in the transient one)."""
    test = np.asarray(test)
    reference = np.asarray(reference)
    if test.shape != reference.shape or test.ndim != 4 or test.shape[-1] != 3:
        raise ValueError(
            f"videos of the same F×H×W×3 shape are needed, got {test.shape} and {reference.shape}")
    if test.dtype != np.uint8 or reference.dtype != np.uint8:
        raise ValueError("videos must be uint8 display values (frameless.to_display)")
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps {fps} is not a positive frame rate")
    metric = _cvvdp(display)
    q, stats = metric.predict(test, reference, dim_order="FHWC",
                              frames_per_second=float(fps))
    return {"jod": float(q), "parts": _channel_jods(metric, stats["Q_per_ch"])}


def _channel_jods(metric, q_per_ch: np.ndarray) -> Dict[str, float]:
    """Each channel's JOD alone, pooled by the metric's own pooling."""
    import torch
    q = torch.as_tensor(q_per_ch, device=metric.device)
    parts = {}
    for c, name in enumerate(CHANNELS[:q.shape[1]]):
        alone = torch.zeros_like(q)
        alone[:, c] = q[:, c]
        parts[name] = float(metric.do_pooling_and_jods(alone))
    return parts


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    d = a.astype(np.int64) - b.astype(np.int64)
    return float(np.sqrt(np.mean(d * d)))


def _ideal_video(scene, times: Sequence[float], size: str, ideal_spp: int, seed: int,
                 max_depth: int, texture_filter: str) -> np.ndarray:
    from ._frameless import to_display
    return np.stack([
        to_display(scene.still(t, size, ideal_spp, seed=seed, max_depth=max_depth,
                               texture_filter=texture_filter, progress=False))
        for t in times
    ])


def _method_video(scene, method: str, rate: float, *, start: float, duration: float,
                  warmup: float, refresh_hz: float, size: str, seed: int,
                  texture_filter: str):
    from . import render, to_display
    frames = list(render(scene, method, rate, start=start, duration=duration, warmup=warmup,
                         refresh_hz=refresh_hz, size=size, seed=seed,
                         texture_filter=texture_filter, progress=False))
    return [t for t, _ in frames], np.stack([to_display(im) for _, im in frames])


def jod_rows(scene, summary: dict, frames: Dict[str, np.ndarray], *,
             max_depth: int = 5, texture_filter: str = "ray-cones",
             display: str = DEFAULT_DISPLAY) -> List[dict]:
    """A JOD for every result row of ``summary`` (``summary.json``'s shape), whose
    per-refresh rows ``frames`` (numpy columns of ``frames.csv``) give the RMS each
    re-rendered frame must have. Returns ``{"method", "rate", "jod", "jod_parts"}``
    rows (``jod_parts``: ``video_jod_parts``'s per-channel JODs)."""
    from ._api import Scene, _scene
    scene = _scene(scene)
    size = f"{summary['width']}x{summary['height']}"
    common = dict(start=summary["start"], duration=summary["duration"],
                  warmup=summary["warmup"], refresh_hz=summary["refresh_hz"], size=size,
                  seed=summary["seed"], texture_filter=texture_filter)
    ideal = None
    out = []
    for row in summary["results"]:
        method, rate = row["method"], row["rate"]
        times, video = _method_video(scene, method, rate, **common)
        if ideal is None:
            ideal = _ideal_video(scene, times, size, summary["ideal_spp"], summary["seed"],
                                 max_depth, texture_filter)
        if video.shape != ideal.shape:
            raise ValueError(f"{method} at {rate}: {video.shape[0]} refreshes rendered, "
                             f"{ideal.shape[0]} ideal images")
        sel = (frames["method"] == method) & (frames["rate"] == rate)
        want = frames["rms"][sel]
        if len(want) != len(video):
            raise ValueError(f"{method} at {rate}: {len(video)} refreshes rendered, "
                             f"{len(want)} in the evaluation's frames")
        for k, (im, ref, rms) in enumerate(zip(video, ideal, want)):
            got = _rms(im, ref)
            if abs(got - rms) > RMS_TOLERANCE:
                raise ValueError(
                    f"{method} at {rate}, refresh {k}: re-rendered RMS {got:.4f} is not the "
                    f"evaluation's {rms:.4f}; were max_depth ({max_depth}), texture_filter "
                    f"({texture_filter}) and the camera path those of the evaluation?")
        got = video_jod_parts(video, ideal, summary["refresh_hz"], display)
        out.append({"method": method, "rate": rate, "jod": got["jod"],
                    "jod_parts": got["parts"]})
    return out


def evaluation_jod(ev, scene, *, max_depth: int = 5, texture_filter: str = "ray-cones",
                   display: str = DEFAULT_DISPLAY) -> None:
    """Add ``jod`` and ``jod_display`` to every result row of ``ev`` (an ``Evaluation``
    from ``frameless.evaluate``)."""
    rows = jod_rows(scene, ev.summary, ev.frames, max_depth=max_depth,
                    texture_filter=texture_filter, display=display)
    for r, j in zip(ev.summary["results"], rows):
        r["jod"] = j["jod"]
        r["jod_display"] = display


def _read_frames_csv(path: Path) -> Dict[str, np.ndarray]:
    import csv
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no rows")
    return {
        "method": np.array([r["method"] for r in rows]),
        "rate": np.array([float(r["rate"]) for r in rows]),
        "rms": np.array([float(r["rms"]) for r in rows]),
    }


def add_to_folder(folder: os.PathLike, scene, camera_path: Optional[os.PathLike] = None, *,
                  max_depth: int = 5, texture_filter: str = "ray-cones",
                  display: str = DEFAULT_DISPLAY) -> Path:
    """Score every method of the ``frameless eval`` output ``folder`` with ColorVideoVDP
    and write ``folder/vdp.json``; ``frameless report folder`` then shows a JOD table.
    ``scene`` and ``camera_path`` must be the evaluation's (``summary.json`` records
    only whether a camera path was used)."""
    from . import Scene
    folder = Path(folder)
    summary = json.loads((folder / "summary.json").read_text())
    if summary.get("camera_path") and camera_path is None:
        raise ValueError(f"{folder}: the evaluation used a camera path; give it (camera_path)")
    sc = scene if isinstance(scene, Scene) else Scene.load(scene, camera_path)
    frames = _read_frames_csv(folder / "frames.csv")
    rows = jod_rows(sc, summary, frames, max_depth=max_depth, texture_filter=texture_filter,
                    display=display)
    try:
        from importlib.metadata import version
        cvvdp_version = version("cvvdp")
    except Exception:
        cvvdp_version = "unknown"
    out = {"metric": "ColorVideoVDP", "version": cvvdp_version, "display": display,
           "frames_per_second": summary["refresh_hz"], "results": rows}
    path = folder / "vdp.json"
    tmp = folder / ".vdp.json.tmp"
    tmp.write_text(json.dumps(out, indent=2) + "\n")
    os.replace(tmp, path)
    return path


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m frameless.vdp",
        description="Add ColorVideoVDP JOD to a frameless eval output folder (vdp.json).")
    p.add_argument("folder", help="a `frameless eval` output folder, or one animation's "
                   "folder of a `frameless table1` output")
    p.add_argument("--scene", required=True, help="the evaluation's scene (file or built-in)")
    p.add_argument("--camera-path", help="the evaluation's camera path, if it had one")
    p.add_argument("--max-depth", type=int, default=5)
    p.add_argument("--texture-filter", default="ray-cones")
    p.add_argument("--display", default=DEFAULT_DISPLAY)
    a = p.parse_args(argv)
    path = add_to_folder(a.folder, a.scene, a.camera_path, max_depth=a.max_depth,
                         texture_filter=a.texture_filter, display=a.display)
    for r in json.loads(path.read_text())["results"]:
        parts = ", ".join(f"{k} {v:.2f}" for k, v in r["jod_parts"].items())
        print(f"{r['method']} {r['rate']:.0f}: JOD {r['jod']:.2f} ({parts})")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
