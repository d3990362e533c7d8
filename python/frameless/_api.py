"""The package's functions and classes; ``frameless`` re-exports the public ones, so
that its namespace holds nothing else."""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import json
import os
import warnings
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, Iterator, Optional, Sequence, Tuple, Union

import numpy as np

from . import _frameless

PathLike = Union[str, "os.PathLike[str]"]
Size = Union[Tuple[int, int], str]
Progress = Union[bool, Callable[[int, int, str], Any]]

# `frameless eval`'s defaults (a test holds them equal to the library's).
DEFAULT_METHODS: Tuple[str, ...] = (
    "framed-60hz",
    "framed-full",
    "full-res-60hz",
    "traditional-frameless",
    "point-tracking",
    "taa",
    "late-warp",
    "taa-warp",
    "adaptive",
)
DEFAULT_RATES: Tuple[str, ...] = ("100k", "400k", "800k")


def write_image(path: PathLike, image: Any) -> None:
    """Write an image as ``frameless`` writes its own: ``.png`` as displayed (clamped,
    8-bit sRGB), ``.exr`` in linear light (docs/colour.md). ``image`` is an ``H×W×3``
    array of display values, as ``Scene.still`` returns: float (0–1), or uint8 bytes
    (0–255) as ``to_display`` returns. The file appears whole or not at all."""
    a = np.asarray(image)
    if a.dtype == np.uint8:
        a = a.astype(np.float32) / np.float32(255.0)
    elif a.dtype.kind == "f":
        a = a.astype(np.float32, copy=False)
    _frameless.write_image(os.fspath(path), a)


def read_image(path: PathLike) -> np.ndarray:
    """An image file's display values, ``H×W×3`` float32: a PNG's bytes / 255, or an
    OpenEXR file's linear light encoded back (docs/colour.md), as ``Scene.still``
    returns them."""
    return _frameless.read_image(os.fspath(path))


def scenes() -> list:
    """The built-in scenes' names, as ``frameless scenes`` lists them."""
    return list(_frameless.defaults()["scenes"])


def _size(size: Size) -> str:
    """``(w, h)`` or ``"WxH"`` as ``--size`` spells it."""
    if isinstance(size, str):
        return size
    try:
        w, h = size
    except (TypeError, ValueError):
        raise ValueError(f"size {size!r}: expected (width, height) or 'WxH'") from None
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (w, h)):
        raise ValueError(f"size {size!r}: width and height must be whole numbers")
    return f"{w}x{h}"


def _names(value: Union[str, Iterable[str]]) -> list:
    """A list, or one comma-separated string as the command line takes it."""
    if isinstance(value, str):
        return value.split(",")
    return [str(v) for v in value]


def _did_you_mean(name: str, known: Sequence[str]) -> str:
    """ "; did you mean 'x'?" for the closest of ``known``, or nothing."""
    close = difflib.get_close_matches(name, known, n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


def _methods(value: Union[str, Iterable[str]]) -> list:
    """Method names as the command line takes them: an old name becomes the current
    one with a FutureWarning naming it, as the command line notes it; an unknown one
    raises ValueError with the closest name."""
    lib = _frameless.defaults()
    renamed = lib["renamed_methods"]
    known = list(dict.fromkeys(lib["all_methods"] + lib["all_live_methods"]))
    out = []
    for name in (n.strip() for n in _names(value)):
        if name in renamed:
            warnings.warn(
                f"method {name!r} is called {renamed[name]!r} now; the old name still works",
                FutureWarning,
                stacklevel=3,
            )
            name = renamed[name]
        elif name not in known:
            raise ValueError(
                f"unknown method {name!r}{_did_you_mean(name, known)} "
                f"(methods: {', '.join(known)})"
            )
        out.append(name)
    return out


def _rates(value: Union[str, float, Iterable[Union[str, float]]]) -> list:
    if isinstance(value, (str, int, float)):
        value = _names(value) if isinstance(value, str) else [value]
    return [str(r) for r in value]


def _cache_dir(cache_dir: Optional[PathLike], no_cache: bool) -> Optional[str]:
    """``--cache-dir`` / ``--no-cache``: $FRAMELESS_CACHE, else ~/.cache/frameless/ideal."""
    if no_cache:
        return None
    if cache_dir is not None:
        return os.fspath(cache_dir)
    if os.environ.get("FRAMELESS_CACHE"):
        return os.environ["FRAMELESS_CACHE"]
    home = os.environ.get("HOME")
    return os.path.join(home, ".cache/frameless/ideal") if home else ".frameless-cache/ideal"


class _Bar:
    """A tqdm bar fed by the native side's ``(done, total, message)`` reports, or the
    caller's own callback, or nothing. The bar opens at the first report of work done
    and shows only after half a second, so that work refused at once, or short, leaves
    no line (a closed bar is erased on a terminal, but stays in a log or notebook)."""

    def __init__(self, progress: Progress, desc: str, unit: str):
        self.bar: Any = None
        self.callback: Optional[Callable[[int, int, str], Any]] = None
        if callable(progress):
            self.callback = progress
        elif progress:
            try:
                from tqdm.auto import tqdm
            except ImportError:
                return
            self._open = lambda total: tqdm(
                total=total or None, desc=desc, unit=f" {unit}", unit_scale=unit == "rays",
                leave=False, delay=0.5,
            )
            self.callback = self._update

    def _update(self, done: int, total: int, msg: str) -> None:
        if self.bar is None:
            if done <= 0:
                return
            self.bar = self._open(total)
        bar = self.bar
        if total and bar.total != total:
            bar.total = total
        if msg:
            bar.set_postfix_str(msg, refresh=False)
        bar.update(done - bar.n)

    def __enter__(self) -> Optional[Callable[[int, int, str], Any]]:
        return self.callback

    def __exit__(self, *exc: Any) -> None:
        if self.bar is not None:
            self.bar.close()



# Video metrics by name: each an optional extra (ColorVideoVDP needs PyTorch), a module
# on top of this one that scores an evaluation's videos with its ``evaluation_jod``. It
# is imported only when asked for, by name, so that this module does not depend on it.
VIDEO_METRICS = {"cvvdp": "frameless.vdp"}

class Scene:
    """A scene, built in or from a file, and the camera path overriding its camera."""

    def __init__(self, native: "_frameless.NativeScene"):
        self._native = native

    @classmethod
    def load(cls, path_or_builtin: PathLike, camera_path: Optional[PathLike] = None) -> "Scene":
        """Load a built-in scene (``toycar``, ``room``, ``terrain``) or a scene file
        (``.aff``, ``.gltf``, ``.glb``, ``.obj``), as ``--scene`` does; ``camera_path``
        is a camera path CSV, as ``--camera-path``. Raises ValueError for an unknown
        name or a malformed file and OSError for one that cannot be read."""
        path = None if camera_path is None else os.fspath(camera_path)
        return cls(_frameless.NativeScene.load(os.fspath(path_or_builtin), path))

    @property
    def name(self) -> str:
        """The name or path it was loaded by."""
        return self._native.name

    @property
    def time_range(self) -> Tuple[float, float]:
        """The scene's animation range, seconds."""
        return self._native.time_range

    @property
    def primitives(self) -> int:
        """Triangles, spheres and cones."""
        return self._native.primitives

    def __repr__(self) -> str:
        path = ", camera path" if self._native.has_camera_path else ""
        return f"Scene({self.name!r}{path}, {self.primitives} primitives)"

    def still(
        self,
        t: float = 0.0,
        size: Size = (256, 256),
        spp: int = 16,
        *,
        seed: int = 1,
        max_depth: int = 5,
        texture_filter: str = "ray-cones",
        progress: Progress = True,
    ) -> np.ndarray:
        """``frameless still``: the image at scene time ``t`` by stratified
        supersampling, ``spp`` samples per pixel, as an ``H×W×3`` float32 array of
        display values, unclamped (``to_display`` gives the PNG's bytes, ``to_linear``
        the OpenEXR file's values; docs/colour.md)."""
        with _Bar(progress, "rendering", "rows") as cb:
            return self._native.still(
                float(t), _size(size), spp, seed, max_depth, texture_filter, cb
            )


def _scene(scene: Union[Scene, PathLike]) -> Scene:
    return scene if isinstance(scene, Scene) else Scene.load(scene)


def _columns(rows: Sequence[dict]) -> Dict[str, np.ndarray]:
    """Rows of one shape as numpy columns: text as str arrays, whole numbers as int64,
    flags as bool, anything else float64 with NaN where a row has no value."""
    cols: Dict[str, np.ndarray] = {}
    for key in rows[0] if rows else ():
        values = [r.get(key) for r in rows]
        present = [v for v in values if v is not None]
        if present and all(isinstance(v, str) for v in present):
            cols[key] = np.array(["" if v is None else v for v in values])
        elif len(present) == len(values) and all(isinstance(v, bool) for v in values):
            cols[key] = np.array(values, dtype=bool)
        elif len(present) == len(values) and all(
            isinstance(v, int) and not isinstance(v, bool) for v in values
        ):
            cols[key] = np.array(values, dtype=np.int64)
        else:
            cols[key] = np.array([np.nan if v is None else v for v in values], dtype=np.float64)
    return cols


@dataclasses.dataclass(repr=False)
class Evaluation:
    """What ``evaluate`` or ``live`` measured.

    ``summary`` is the run's ``summary.json`` as Python data (its ``results`` are the
    table's rows); ``frames`` is the per-refresh table (``frames.csv``, unrounded) as
    numpy columns; ``frames_df`` the same as a pandas DataFrame where pandas is
    installed, else None."""

    summary: Dict[str, Any]
    frames: Dict[str, np.ndarray]
    frames_df: Any = None

    @property
    def results(self) -> list:
        """The summary's rows: one per method (and rate, for ``evaluate``)."""
        return self.summary["results"]

    def __repr__(self) -> str:
        rows = self.results
        methods = list(dict.fromkeys(r["method"] for r in rows))
        rates = list(dict.fromkeys(r["rate"] for r in rows if "rate" in r))
        def count(n: int, what: str) -> str:
            return f"{n} {what}" + ("" if n == 1 else "s")

        shape = count(len(methods), "method") + (f" × {count(len(rates), 'rate')}" if rates else "")
        scene = self.summary.get("scene", "?")
        n = len(next(iter(self.frames.values()), ()))
        return f"<Evaluation of {scene!r}: {shape}, {n} frame rows; .results, .frames>"

    @classmethod
    def _from_json(cls, summary: str, frames: str) -> "Evaluation":
        cols = _columns(json.loads(frames))
        try:
            import pandas
        except ImportError:
            table = None
        else:
            table = pandas.DataFrame(cols)
        return cls(json.loads(summary), cols, table)


def evaluate(
    scene: Union[Scene, PathLike],
    methods: Union[str, Iterable[str]] = DEFAULT_METHODS,
    rates: Union[str, float, Iterable[Union[str, float]]] = DEFAULT_RATES,
    start: float = 0.0,
    duration: float = 1.0,
    *,
    size: Size = (256, 256),
    refresh_hz: float = 60.0,
    seed: int = 1,
    ideal_spp: int = 16,
    warmup: float = 1.0,
    max_depth: int = 5,
    texture_filter: str = "ray-cones",
    flip_every: int = 1,
    cache_dir: Optional[PathLike] = None,
    no_cache: bool = False,
    recon: str = "cpu",
    progress: Progress = True,
    video_metric: Optional[str] = None,
    trace: str = "cpu",
    video_display: str = "standard_fhd",
) -> Evaluation:
    """``frameless eval``: every method at every rate against the ideal image at each
    refresh of the window ``[start, start + duration)``, after ``warmup`` seconds.
    Rates are samples per second (``"400k"``, ``1.5e6``). The ideal images are cached
    as the command line caches them (``cache_dir``, ``no_cache``). No files are
    written; the numbers are those of the command's ``summary.json``.
    ``video_metric="cvvdp"`` adds ColorVideoVDP's JOD for the display model
    ``video_display`` to every result row (``jod``; the extra ``frameless[vdp]``, see
    ``frameless.vdp``). ``recon`` is ``--recon``: ``"cpu"`` (the reference) or
    ``"auto"``; this module is built without the GPU reconstructor, so ``"gpu"``
    raises ValueError and ``"auto"`` runs on the CPU. ``trace`` is ``--trace``, the
    same three choices for the tracer, and the same refusal of ``"gpu"`` here."""
    if video_metric is not None and video_metric not in VIDEO_METRICS:
        raise ValueError(f"video_metric {video_metric!r}: the one video metric is 'cvvdp'")
    native = _scene(scene)._native
    with _Bar(progress, "evaluating", "rays") as cb:
        summary, frames = _frameless.evaluate(
            native, _methods(methods), _rates(rates), float(start), float(duration),
            _size(size), float(refresh_hz), seed, ideal_spp, float(warmup), max_depth,
            texture_filter, flip_every, _cache_dir(cache_dir, no_cache), recon, cb, trace,
        )
    ev = Evaluation._from_json(summary, frames)
    if video_metric is not None:
        score = getattr(importlib.import_module(VIDEO_METRICS[video_metric]), "evaluation_jod")
        score(ev, _scene(scene), max_depth=max_depth, texture_filter=texture_filter,
              display=video_display)
    return ev


def live(
    scene: Union[Scene, PathLike],
    methods: Optional[Union[str, Iterable[str]]] = None,
    *,
    start: float = 0.0,
    duration: float = 3.0,
    warmup: float = 1.0,
    size: Size = (256, 256),
    refresh_hz: float = 60.0,
    repeat: int = 1,
    threads: Optional[int] = None,
    seed: int = 1,
    ideal_spp: int = 16,
    max_depth: int = 5,
    texture_filter: str = "ray-cones",
    cache_dir: Optional[PathLike] = None,
    no_cache: bool = False,
    recon: str = "cpu",
    progress: Progress = True,
    seconds: Optional[float] = None,
    trace: str = "cpu",
    image_budget: Optional[float] = None,
    ring_factor: Optional[float] = None,
    max_radius: Optional[float] = None,
    view_ahead: bool = True,
    late_samples: bool = True,
) -> Evaluation:
    """``frameless live``: the real-time methods (default: all) one after another on
    this machine for ``duration`` seconds of wall time each, every displayed refresh
    scored against the ideal image at its scan-out time. ``threads`` sizes the pipeline
    as ``--threads`` does. Ctrl-C stops it when the run in progress ends. ``seconds``
    is ``duration``'s old name (a FutureWarning says so). ``recon`` and ``trace`` are
    ``--recon`` and ``--trace`` (see ``evaluate``). ``image_budget``, ``ring_factor``
    and ``max_radius`` are the adaptive method's ``--image-budget``, ``--ring-factor``
    and ``--max-radius`` (None: its defaults). ``view_ahead=False`` is
    ``--no-view-ahead``: every method traces a moving view where it is, not where it will
    be when shown. ``late_samples=False`` is adaptive's ``--no-late-samples``: a moving
    view's image is built from the samples in hand when its build starts only, without
    the samples traced while its ring is placed and splatted."""
    if seconds is not None:
        warnings.warn("live(seconds=...) is live(duration=...) now; the old name still works",
                      FutureWarning, stacklevel=2)
        duration = seconds
    native = _scene(scene)._native
    names = None if methods is None else _methods(methods)
    with _Bar(progress, "live", "refreshes") as cb:
        summary, frames = _frameless.live(
            native, names, float(start), float(duration), float(warmup), _size(size),
            float(refresh_hz), repeat, threads, seed, ideal_spp, max_depth,
            texture_filter, _cache_dir(cache_dir, no_cache), recon, cb, trace,
            image_budget, ring_factor, max_radius, bool(view_ahead), bool(late_samples),
        )
    return Evaluation._from_json(summary, frames)


class Render:
    """The ``(time, image)`` pairs of ``render``: one per refresh, ``len()`` of them.
    The method traces one refresh ahead of the consumer; dropping the iterator stops
    it."""

    def __init__(self, native: "_frameless.NativeRender", progress: Progress):
        self._native = native
        self._progress = progress

    def __len__(self) -> int:
        return self._native.len

    def __repr__(self) -> str:
        return f"<Render: {len(self)} refreshes>"

    def __iter__(self) -> Iterator[Tuple[float, np.ndarray]]:
        with _Bar(self._progress, "rendering", "refreshes") as cb:
            for k, item in enumerate(self._native, 1):
                if cb is not None:
                    cb(k, len(self), "")
                yield item


def render(
    scene: Union[Scene, PathLike],
    method: str = "adaptive",
    rate: Union[str, float] = "400k",
    *,
    start: float = 0.0,
    duration: float = 1.0,
    warmup: float = 1.0,
    refresh_hz: float = 60.0,
    size: Size = (256, 256),
    seed: int = 1,
    max_depth: int = 5,
    texture_filter: str = "ray-cones",
    recon: str = "cpu",
    progress: Progress = True,
    trace: str = "cpu",
) -> Render:
    """``frameless render``: what ``method`` displays at each refresh of
    ``[start, start + duration)`` under the simulated clock at ``rate`` samples per
    second. Yields ``(time, image)``, the image ``H×W×3`` float32 display values
    (``to_linear`` gives ``--format exr``'s frames, ``to_display`` the PNG frames'
    bytes). ``recon`` and ``trace`` are ``--recon`` and ``--trace`` (see
    ``evaluate``). The settings are checked here, before the first image."""
    rates = _rates(rate)
    if len(rates) != 1:
        raise ValueError(f"rate {rate!r}: render runs one rate")
    native = _frameless.NativeRender(
        _scene(scene)._native, _methods(method)[0], rates[0], float(start), float(duration),
        float(warmup), _size(size), float(refresh_hz), seed, max_depth, texture_filter,
        recon, trace,
    )
    return Render(native, progress)
