"""The evaluation's image metrics on any two images: RMS error, PSNR and FLIP, and the
per-pixel maps of RMS and FLIP. An image is an ``H×W×3`` array of display values
(float, as ``Scene.still`` returns; uint8 bytes, as ``to_display`` returns) or a
``.png`` or ``.exr`` file. Like ``frameless eval``, every metric compares what the
display shows: both images clamped and rounded to 8 bits (docs/colour.md), so the
numbers are the evaluation's for the same pair."""

import os as _os
from typing import Any as _Any, Dict as _Dict

import numpy as _np

from . import _frameless

__all__ = ["rms", "psnr", "flip", "rms_map", "flip_map", "compare"]


def _displayed(image: _Any) -> _np.ndarray:
    """``image`` as the display shows it: ``H×W×3`` uint8."""
    if isinstance(image, (str, _os.PathLike)):
        image = _frameless.read_image(_os.fspath(image))
    a = _np.asarray(image)
    if a.dtype == _np.uint8:
        return _np.ascontiguousarray(a)
    if a.dtype.kind != "f":
        raise TypeError(
            f"an image is an H×W×3 float (display values) or uint8 array, or a .png or "
            f".exr path; this one has dtype {a.dtype}"
        )
    return _frameless.to_display(a.astype(_np.float32, copy=False))


def rms(reference: _Any, test: _Any) -> float:
    """RMS error over all pixels and channels, in 0–255 units."""
    return _frameless.rms(_displayed(reference), _displayed(test))


def psnr(reference: _Any, test: _Any) -> float:
    """PSNR in dB (peak 255), capped at 99 dB for identical images."""
    return _frameless.psnr(_displayed(reference), _displayed(test))


def flip(reference: _Any, test: _Any) -> float:
    """Mean LDR-FLIP error (0: no perceived difference; 67 pixels per degree)."""
    return _frameless.flip(_displayed(reference), _displayed(test))


def rms_map(reference: _Any, test: _Any) -> _np.ndarray:
    """Each pixel's RMS error over its channels, ``H×W`` float64 in 0–255 units (its
    mean square is ``rms``'s square)."""
    r, t = _displayed(reference), _displayed(test)
    if r.shape != t.shape:
        raise ValueError(f"the images differ in shape: reference {r.shape}, test {t.shape}")
    d = r.astype(_np.float64) - t.astype(_np.float64)
    return _np.sqrt((d * d).mean(axis=2))


def flip_map(reference: _Any, test: _Any) -> _np.ndarray:
    """Each pixel's FLIP error, ``H×W`` float32 in [0, 1] (``flip`` is its mean)."""
    return _frameless.flip_map(_displayed(reference), _displayed(test))


def compare(reference: _Any, test: _Any) -> _Dict[str, float]:
    """``{"rms": …, "psnr": …, "flip": …}`` of one pair."""
    r, t = _displayed(reference), _displayed(test)
    return {
        "rms": _frameless.rms(r, t),
        "psnr": _frameless.psnr(r, t),
        "flip": _frameless.flip(r, t),
    }
