"""The native extension: the `frameless` library built with PyO3. The `frameless`
package wraps it with defaults, progress bars and tables; use that instead."""

from typing import Any, Callable, Iterator, Optional, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

ProgressCallback = Optional[Callable[[int, int, str], Any]]

def defaults() -> dict:
    """The library's defaults of `eval`, `live` and `still`, the built-in scenes and
    the method names."""

def to_display(image: npt.NDArray[np.float32]) -> npt.NDArray[np.uint8]:
    """An H×W×3 image as displayed and written to PNG: clamped to [0, 1] and rounded
    to 8 bits."""

def to_linear(image: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """An H×W×3 image in linear light, as written to OpenEXR (docs/colour.md)."""

def write_image(path: str, image: npt.NDArray[np.float32]) -> None:
    """Write an image: `.png` as displayed, `.exr` in linear light."""

def read_image(path: str) -> npt.NDArray[np.float32]:
    """A `.png` or `.exr` file's display values, H×W×3 float32."""

def main(argv: list) -> int:
    """Run the `frameless` command (`argv[0]` is the program's name); its exit status."""

def rms(reference: npt.NDArray[np.uint8], test: npt.NDArray[np.uint8]) -> float:
    """RMS error of two H×W×3 byte images, 0–255."""

def psnr(reference: npt.NDArray[np.uint8], test: npt.NDArray[np.uint8]) -> float:
    """PSNR of two H×W×3 byte images, dB."""

def flip(reference: npt.NDArray[np.uint8], test: npt.NDArray[np.uint8]) -> float:
    """Mean LDR-FLIP error of two H×W×3 byte images."""

def flip_map(
    reference: npt.NDArray[np.uint8], test: npt.NDArray[np.uint8]
) -> npt.NDArray[np.float32]:
    """Per-pixel LDR-FLIP error, H×W float32."""

class NativeScene:
    """A loaded scene and the camera path overriding its camera."""

    name: str
    time_range: Tuple[float, float]
    primitives: int
    has_camera_path: bool
    @staticmethod
    def load(name: str, camera_path: Optional[str] = None) -> "NativeScene":
        """A built-in scene by name or a scene file; raises ValueError or OSError with
        the command line's message."""
    def still(
        self,
        time: float,
        size: str,
        spp: int,
        seed: int,
        max_depth: int,
        texture_filter: str,
        progress: ProgressCallback = None,
    ) -> npt.NDArray[np.float32]:
        """`frameless still`'s image (display values), H×W×3 float32."""

def evaluate(
    scene: NativeScene,
    methods: list,
    rates: list,
    start: float,
    duration: float,
    size: str,
    refresh_hz: float,
    seed: int,
    ideal_spp: int,
    warmup: float,
    max_depth: int,
    texture_filter: str,
    flip_every: int,
    cache_dir: Optional[str],
    recon: str = "cpu",
    progress: ProgressCallback = None,
    trace: str = "cpu",
) -> Tuple[str, str]:
    """`frameless eval`: (summary JSON, per-frame rows JSON)."""

def live(
    scene: NativeScene,
    methods: Optional[list],
    start: float,
    seconds: float,
    warmup: float,
    size: str,
    refresh_hz: float,
    repeat: int,
    threads: Optional[int],
    seed: int,
    ideal_spp: int,
    max_depth: int,
    texture_filter: str,
    cache_dir: Optional[str],
    recon: str = "cpu",
    progress: ProgressCallback = None,
    trace: str = "cpu",
    image_budget: Optional[float] = None,
    ring_factor: Optional[float] = None,
    max_radius: Optional[float] = None,
    view_ahead: bool = True,
    late_samples: bool = True,
) -> Tuple[str, str]:
    """`frameless live`: (summary JSON, per-refresh rows JSON)."""

class NativeRender:
    """`frameless render` as an iterator of (time, H×W×3 float32 image of display values)."""

    len: int
    def __init__(
        self,
        scene: NativeScene,
        method: str,
        rate: str,
        start: float,
        duration: float,
        warmup: float,
        size: str,
        refresh_hz: float,
        seed: int,
        max_depth: int,
        texture_filter: str,
        recon: str = "cpu",
        trace: str = "cpu",
    ) -> None: ...
    def __iter__(self) -> Iterator[Tuple[float, npt.NDArray[np.float32]]]: ...
    def __next__(self) -> Tuple[float, npt.NDArray[np.float32]]: ...
