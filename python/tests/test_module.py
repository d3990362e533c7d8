"""The `frameless` module against the `frameless` binary: a still equals the command's
PNG and OpenEXR files (the EXR bit for bit), `evaluate` and `render` give the numbers
and images of `frameless eval` and `frameless render`, a bad setting raises ValueError
with the command's reason in Python's terms, `frameless.metrics` gives the evaluation's
numbers, the `frameless` console script and `python -m frameless` are the command, and
long work stops on Ctrl-C.

Needs the frameless binary: $FRAMELESS_BIN, else target/release/frameless (cargo build --release).
"""

import _thread
import inspect
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from PIL import Image

import frameless

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def binary() -> Path:
    p = Path(os.environ.get("FRAMELESS_BIN") or REPO / "target" / "release" / "frameless")
    if not p.is_file():
        pytest.fail(f"no frameless binary at {p}: run `cargo build` or set FRAMELESS_BIN")
    return p


def cli(binary, *args, ok=True):
    p = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True)
    assert (p.returncode == 0) == ok, p.stderr
    return p


def read_exr(path: Path) -> np.ndarray:
    channels = OpenEXR.File(str(path)).channels()
    if "RGB" in channels:
        return np.asarray(channels["RGB"].pixels)
    return np.stack([np.asarray(channels[c].pixels) for c in "RGB"], axis=-1)


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


@pytest.fixture(scope="module")
def toycar():
    return frameless.Scene.load("toycar")


def test_still_equals_the_commands_png_and_exr(tmp_path, binary, toycar):
    args = ["--scene", "toycar", "--time", "0.75", "--size", "48x32", "--spp", "4", "--seed", "3"]
    cli(binary, "still", *args, "--out", tmp_path / "s.exr")
    cli(binary, "still", *args, "--out", tmp_path / "s.png")
    img = toycar.still(0.75, size=(48, 32), spp=4, seed=3, progress=False)
    assert img.shape == (32, 48, 3) and img.dtype == np.float32
    exr = read_exr(tmp_path / "s.exr")
    assert exr.shape == img.shape
    assert np.array_equal(bits(exr), bits(frameless.to_linear(img))), "EXR values differ"
    png = np.asarray(Image.open(tmp_path / "s.png").convert("RGB"))
    assert np.array_equal(png, frameless.to_display(img))
    # Not a constant image: the comparison above could tell two renderings apart.
    assert img.std() > 0.01


def test_still_defaults_are_the_commands(tmp_path, binary, toycar):
    cli(binary, "still", "--spp", "1", "--format", "exr", "--out", tmp_path / "d.exr")
    img = toycar.still(spp=1, progress=False)
    assert np.array_equal(bits(read_exr(tmp_path / "d.exr")), bits(frameless.to_linear(img)))


def without_timing(summary: dict) -> dict:
    assert "timing" in summary
    return {k: v for k, v in summary.items() if k != "timing"}


def test_evaluate_gives_the_numbers_of_summary_json(tmp_path, binary, toycar):
    methods, rates = ["traditional-frameless", "adaptive", "taa"], ["200k", "400k"]
    cli(
        binary, "eval", "--scene", "toycar", "--size", "40x32", "--duration", "0.2",
        "--warmup", "0.25", "--method", ",".join(methods), "--rate", ",".join(rates),
        "--no-cache", "--out", tmp_path / "eval",
    )
    want = json.loads((tmp_path / "eval" / "summary.json").read_text())
    calls = []
    ev = frameless.evaluate(
        toycar, methods=methods, rates=rates, duration=0.2, warmup=0.25, size=(40, 32),
        no_cache=True, progress=lambda *a: calls.append(a),
    )
    assert without_timing(ev.summary) == without_timing(want)
    assert len(ev.results) == len(methods) * len(rates)
    # The per-frame table holds every method, rate and frame; its means are the rows'.
    n = ev.summary["results"][0]["frames"]
    assert len(ev.frames["rms"]) == len(ev.results) * n
    for row in ev.results:
        pick = (ev.frames["method"] == row["method"]) & (ev.frames["rate"] == row["rate"])
        assert pick.sum() == n
        assert ev.frames["rms"][pick].mean() == pytest.approx(row["rms_mean"], rel=1e-9)
    done, total, _ = calls[-1]
    assert total > 0 and done == total


def test_render_yields_the_commands_exr_frames(tmp_path, binary, toycar):
    args = ["--size", "32x24", "--duration", "0.05", "--warmup", "0.1", "--rate", "200k"]
    cli(binary, "render", "--scene", "toycar", *args, "--format", "exr", "--out", tmp_path / "r")
    frames = list(
        frameless.render(toycar, "adaptive", "200k", size=(32, 24), duration=0.05, warmup=0.1)
    )
    files = sorted((tmp_path / "r").glob("frame_*.exr"))
    assert len(frames) == len(files) == 3
    for k, ((t, img), f) in enumerate(zip(frames, files)):
        assert t == pytest.approx(k / 60.0)
        assert np.array_equal(bits(frameless.to_linear(img)), bits(read_exr(f))), f.name


# Settings the library checks: the message is the command's, the setting named by its
# Python keyword (`duration`) where the command names its option (`--duration`).
LIBRARY_CHECKED = [
    (["eval", "--duration", "-1"], lambda s: frameless.evaluate(s, duration=-1)),
    (["eval", "--rate", "1", "--method", "framed-60hz"],
     lambda s: frameless.evaluate(s, methods="framed-60hz", rates=1)),
    (["eval", "--method", "adaptive,adaptive"],
     lambda s: frameless.evaluate(s, methods=["adaptive", "adaptive"])),
    (["eval", "--size", "4096x4097"], lambda s: frameless.evaluate(s, size=(4096, 4097))),
    (["render", "--warmup", "-2"], lambda s: frameless.render(s, warmup=-2)),
    (["live", "--duration", "0"], lambda s: frameless.live(s, duration=0)),
    (["live", "--ring-factor", "100"], lambda s: frameless.live(s, ring_factor=100)),
]

# Values clap parses on the command line ("invalid value '…' for '--opt <OPT>':
# <reason>"): the reason is the command's.
CLAP_PARSED = [
    (["eval", "--size", "0x10"], lambda s: frameless.evaluate(s, size=(0, 10))),
    (["eval", "--rate", "fast"], lambda s: frameless.evaluate(s, rates="fast")),
    (["still", "--spp", "0"], lambda s: s.still(spp=0)),
    (["still", "--max-depth", "65"], lambda s: s.still(max_depth=65)),
]


def cli_error(binary, *args) -> str:
    p = cli(binary, *args, ok=False)
    # Progress lines may come before the error when stderr is a pipe, and clap adds a
    # hint after it.
    errors = [line for line in p.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, p.stderr
    return errors[0]


def in_python_terms(message: str) -> str:
    """A Python message as the command line words it: its leading keyword as the
    option (`duration` -> `--duration`)."""
    first, _, rest = message.partition(" ")
    if re.fullmatch(r"[a-z_]+", first) and first in PYTHON_KEYWORDS:
        return f"--{first.replace('_', '-')} {rest}"
    return message


PYTHON_KEYWORDS = {"duration", "warmup", "start", "size", "methods", "rates", "refresh_hz"}


@pytest.mark.parametrize("cli_args, call", LIBRARY_CHECKED)
def test_bad_settings_raise_value_error_with_the_commands_reason(
    tmp_path, binary, toycar, cli_args, call
):
    stderr = cli_error(binary, *cli_args, "--out", tmp_path / "x")
    with pytest.raises(ValueError) as e:
        call(toycar)
    assert "--" not in str(e.value), e.value
    assert stderr == f"error: {in_python_terms(str(e.value))}"


@pytest.mark.parametrize("cli_args, call", CLAP_PARSED)
def test_bad_values_raise_value_error_with_the_commands_reason(
    tmp_path, binary, toycar, cli_args, call
):
    stderr = cli_error(binary, *cli_args, "--out", tmp_path / "x.png")
    with pytest.raises(ValueError) as e:
        call(toycar)
    message = str(e.value)
    assert "--" not in message, message
    # "spp=0 is not in …" names the keyword and its value; the reason follows.
    named = re.match(r"[a-z_]+=\S+ ", message)
    reason = message[named.end():] if named else message.split(": ", 1)[-1]
    assert len(reason) > 10 and reason in stderr, (message, stderr)


def test_unknown_scene_and_missing_file_messages(tmp_path, binary):
    cases = [("toycat", ValueError, "did you mean `toycar`"),
             (str(tmp_path / "no.obj"), OSError, "no.obj")]
    for name, exc, words in cases:
        stderr = cli_error(binary, "still", "--scene", name, "--out", tmp_path / "x.png")
        with pytest.raises(exc) as e:
            frameless.Scene.load(name)
        assert stderr == f"error: {e.value}" and words in stderr


def test_bart_kitchen_still_equals_the_commands(tmp_path, binary):
    # As the Rust tests: skipped without FRAMELESS_BART_DIR, failing if it names a
    # folder without the scene.
    bart = os.environ.get("FRAMELESS_BART_DIR")
    if not bart:
        pytest.skip("FRAMELESS_BART_DIR is not set")
    kitchen = Path(bart) / "kitchen" / "kitchen.aff"
    assert kitchen.is_file(), f"FRAMELESS_BART_DIR is set but {kitchen} is missing"
    args = ["--time", "2", "--size", "40x30", "--spp", "2"]
    cli(binary, "still", "--scene", kitchen, *args, "--out", tmp_path / "k.exr")
    img = frameless.Scene.load(kitchen).still(2.0, size=(40, 30), spp=2, progress=False)
    assert np.array_equal(bits(frameless.to_linear(img)), bits(read_exr(tmp_path / "k.exr")))
    assert img.std() > 0.01


def test_python_defaults_are_the_librarys():
    lib = frameless._frameless.defaults()
    ev = inspect.signature(frameless.evaluate).parameters
    assert list(frameless.DEFAULT_METHODS) == lib["evaluate"]["methods"]
    assert [float(r[:-1]) * 1e3 for r in frameless.DEFAULT_RATES] == lib["evaluate"]["rates"]
    for k in ("start", "duration", "refresh_hz", "seed", "ideal_spp", "warmup", "max_depth",
              "flip_every"):
        assert ev[k].default == lib["evaluate"][k], k
    assert tuple(ev["size"].default) == tuple(lib["evaluate"]["size"])
    st = inspect.signature(frameless.Scene.still).parameters
    for k in ("seed", "spp", "max_depth"):
        assert st[k].default == lib["still"][k], k
    assert tuple(st["size"].default) == tuple(lib["still"]["size"]) == tuple(ev["size"].default)
    assert st["seed"].default == ev["seed"].default
    lv = inspect.signature(frameless.live).parameters
    assert lv["duration"].default == lib["live"]["duration"]
    for k in ("start", "warmup", "refresh_hz", "repeat", "seed", "ideal_spp",
              "max_depth"):
        assert lv[k].default == lib["live"][k], k
    assert tuple(lv["size"].default) == tuple(lib["live"]["size"])
    assert frameless.scenes() == lib["scenes"] and "toycar" in lib["scenes"]


def test_ctrl_c_stops_a_long_still(toycar):
    # Long enough to take many seconds here; Ctrl-C a quarter second in. A process
    # started in the background by a shell ignores SIGINT, and then interrupt_main
    # does nothing: Python's own handler is put in place for the test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.25, _thread.interrupt_main)
        t0 = time.monotonic()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            toycar.still(size=(512, 384), spp=4096, progress=False)
        assert time.monotonic() - t0 < 5.0
    finally:
        signal.signal(signal.SIGINT, previous)
    # The module still works afterwards.
    assert toycar.still(size=(8, 8), spp=1, progress=False).shape == (8, 8, 3)


def test_long_work_releases_the_gil(toycar):
    # A Python thread keeps counting while a still renders (here near 900 ticks a
    # second); holding the GIL for the whole render would leave it at (nearly) none.
    ticks, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            ticks[0] += 1
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    t0 = time.monotonic()
    toycar.still(size=(192, 144), spp=128, progress=False)
    seconds = time.monotonic() - t0
    stop.set()
    t.join()
    assert seconds > 0.2, "the render is too short to tell"
    assert ticks[0] > 10 * seconds, (ticks[0], seconds)


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((4, 6, 3), np.float64),
        np.zeros((4, 6, 3), np.int64),
        np.zeros((4, 6), np.float32),
    ],
    ids=["float64", "int64", "2-D"],
)
def test_to_display_names_the_array_it_takes(image):
    with pytest.raises(TypeError) as e:
        frameless.to_display(image)
    message = str(e.value)
    assert "H×W×3 float32" in message, message
    assert str(image.shape) in message and str(image.dtype) in message, message
    assert frameless.to_display(np.zeros((4, 6, 3), np.float32)).shape == (4, 6, 3)


# Python exits while a daemon thread is inside a still. A C-level exit function that
# reads stdin holds the interpreter at the end of its finalisation until the test
# closes stdin, so the still's thread, whose waits end every tenth of a second, would
# ask for the GIL back during finalisation every time, not only on a loaded machine.
EXIT_INSIDE_A_STILL = """
import ctypes, threading
import frameless

scene = frameless.Scene.load("toycar")
inside = threading.Event()

def still():
    scene.still(size=(512, 384), spp=4096, progress=lambda done, total, what: inside.set())

threading.Thread(target=still, daemon=True).start()
assert inside.wait(60)
ctypes.pythonapi.Py_AtExit(ctypes.cast(ctypes.CDLL(None).getchar, ctypes.c_void_p))
print("inside", flush=True)
"""


def test_exit_with_a_thread_inside_a_still_is_clean():
    p = subprocess.Popen(
        [sys.executable, "-c", EXIT_INSIDE_A_STILL],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert p.stdout.readline().strip() == "inside", p.stderr.read()
        # Ten of the thread's waits: it would have asked for the GIL by then.
        time.sleep(1.0)
        p.stdin.close()
        p.wait(60)
    finally:
        p.kill()
    err = p.stderr.read()
    assert p.returncode == 0, (p.returncode, err)
    assert "FATAL" not in err, err


def test_one_name_per_method_and_old_names_warn(toycar):
    # `framed-full` is a method of both clocks; `framed`, the real-time pipeline's old
    # name for it, still works with a FutureWarning naming the new one.
    lib = frameless._frameless.defaults()
    assert "framed-full" in lib["all_methods"] and "framed-full" in lib["all_live_methods"]
    assert lib["renamed_methods"] == {"framed": "framed-full"}
    with pytest.warns(FutureWarning, match="'framed-full'"):
        ev = frameless.evaluate(toycar, methods="framed", rates="100k", duration=0.05,
                                size=(16, 16), no_cache=True, progress=False)
    assert ev.results[0]["method"] == "framed-full"
    with pytest.raises(ValueError, match="did you mean 'framed-full'"):
        frameless.evaluate(toycar, methods="framed-ful", progress=False)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1's encoding, written here from the standard (docs/colour.md)."""
    a = np.abs(linear.astype(np.float64))
    enc = np.where(a <= 0.0031308, a * 12.92, 1.055 * a ** (1 / 2.4) - 0.055)
    return np.copysign(enc, linear)


def test_write_image_writes_the_commands_files_which_agree_through_srgb(tmp_path, binary, toycar):
    args = ["--scene", "toycar", "--time", "0.5", "--size", "40x24", "--spp", "2"]
    cli(binary, "still", *args, "--format", "exr", "-o", tmp_path / "c.exr")
    cli(binary, "still", *args, "-o", tmp_path / "c.png")
    img = toycar.still(0.5, size=(40, 24), spp=2, progress=False)
    frameless.write_image(tmp_path / "p.exr", img)
    frameless.write_image(tmp_path / "p.png", img)
    exr, png = read_exr(tmp_path / "c.exr"), np.asarray(Image.open(tmp_path / "c.png"))
    assert np.array_equal(bits(read_exr(tmp_path / "p.exr")), bits(exr))
    assert np.array_equal(np.asarray(Image.open(tmp_path / "p.png")), png)
    # The EXR holds linear light: its sRGB encoding, clamped and rounded, is the PNG
    # (to within float rounding at a rounding boundary).
    shown = np.clip(srgb_encode(exr), 0, 1) * 255
    assert np.all(np.abs(shown - png) <= 0.5 + 1e-3)
    # Bytes as to_display gives them write the same PNG.
    frameless.write_image(tmp_path / "b.png", frameless.to_display(img))
    assert np.array_equal(np.asarray(Image.open(tmp_path / "b.png")), png)
    with pytest.raises(ValueError, match=r"\.jpg"):
        frameless.write_image(tmp_path / "x.jpg", img)


def test_namespace_and_reprs_are_short():
    public = {n for n in dir(frameless) if not n.startswith("_")}
    assert public == set(frameless.__all__), public ^ set(frameless.__all__)
    for stray in ("Any", "np", "os", "json", "annotations", "dataclasses"):
        assert stray not in public, stray
    scene = frameless.Scene.load("toycar")
    ev = frameless.evaluate(scene, methods="adaptive", rates="100k", duration=0.05,
                            size=(16, 16), no_cache=True, progress=False)
    assert len(repr(ev)) < 120 and "toycar" in repr(ev), repr(ev)
    assert len(repr(frameless.render(scene, size=(8, 8), duration=0.05))) < 60


def test_errors_name_keywords_and_suggest(toycar):
    cases = [
        (lambda: toycar.still(spp=0), "spp=0"),
        (lambda: frameless.evaluate(toycar, texture_filter="raycones"), "did you mean 'ray-cones'"),
        (lambda: frameless.evaluate(toycar, recon="cpx"), "did you mean 'cpu'"),
        (lambda: frameless.render(toycar, "adaptve"), "did you mean 'adaptive'"),
    ]
    for call, words in cases:
        with pytest.raises(ValueError) as e:
            call()
        assert words in str(e.value) and "--" not in str(e.value), e.value


def test_recon_is_the_commands(toycar):
    # This module is built without the GPU reconstructor: gpu is refused with the
    # library's reason, auto runs on the CPU and gives the CPU's numbers.
    with pytest.raises(ValueError, match="recon=.gpu.: .*GPU"):
        frameless.evaluate(toycar, recon="gpu", progress=False)
    kw = dict(methods="adaptive", rates="100k", duration=0.05, size=(16, 16), no_cache=True,
              progress=False)
    cpu = frameless.evaluate(toycar, recon="cpu", **kw)
    auto = frameless.evaluate(toycar, recon="auto", **kw)
    assert cpu.results[0]["rms_mean"] == auto.results[0]["rms_mean"]


def test_trace_is_the_commands(toycar):
    # `trace=` beside `recon=`: this module is built without GPU support, so gpu is
    # refused with the library's reason, a typo gets the command line's suggestion, and
    # auto traces on the CPU, recorded in the summary.
    with pytest.raises(ValueError, match="trace=.gpu.: .*GPU"):
        frameless.evaluate(toycar, trace="gpu", progress=False)
    with pytest.raises(ValueError, match="did you mean 'cpu'"):
        frameless.evaluate(toycar, trace="cpx", progress=False)
    with pytest.raises(ValueError, match="trace=.gpu.: .*GPU"):
        frameless.render(toycar, "adaptive", trace="gpu", progress=False)
    with pytest.raises(ValueError, match="trace=.gpu.: .*GPU"):
        frameless.live(toycar, "adaptive", trace="gpu", progress=False)
    kw = dict(methods="traditional-frameless", rates="100k", duration=0.05, size=(16, 16),
              no_cache=True, progress=False)
    cpu = frameless.evaluate(toycar, trace="cpu", **kw)
    auto = frameless.evaluate(toycar, trace="auto", **kw)
    assert cpu.results[0]["rms_mean"] == auto.results[0]["rms_mean"]
    assert auto.summary["trace"] == {"device": "cpu", "adapter": None}


def test_live_traces_the_view_ahead_unless_asked_not_to(toycar):
    # `view_ahead=False` is `--no-view-ahead`: the summary records which it was.
    kw = dict(methods="traditional-frameless", duration=0.05, warmup=0.05, size=(16, 16),
              ideal_spp=1, no_cache=True, progress=False)
    assert frameless.live(toycar, **kw).summary["view_ahead"] is True
    assert frameless.live(toycar, view_ahead=False, **kw).summary["view_ahead"] is False


def test_live_takes_late_samples_unless_told_not_to(toycar):
    # `late_samples=False` is `--no-late-samples`: the summary's adaptive settings say so.
    kw = dict(methods="adaptive", duration=0.05, warmup=0.05, size=(16, 16),
              ideal_spp=1, no_cache=True, progress=False)
    assert frameless.live(toycar, **kw).summary["adaptive"]["late_samples"] is True
    off = frameless.live(toycar, late_samples=False, **kw)
    assert off.summary["adaptive"]["late_samples"] is False


def test_metrics_are_the_evaluations(tmp_path, binary, toycar):
    # Two of the command's own files, compared by the module as `eval` compares images:
    # the numbers follow the definitions (RMS of the bytes, PSNR of the RMS), and the
    # maps average to them.
    args = ["--scene", "toycar", "--size", "32x24", "--time", "0.5"]
    cli(binary, "still", *args, "--spp", "1", "-o", tmp_path / "a.png")
    cli(binary, "still", *args, "--spp", "16", "--format", "exr", "-o", tmp_path / "b.exr")
    a, b = tmp_path / "a.png", tmp_path / "b.exr"
    shown_a = np.asarray(Image.open(a).convert("RGB")).astype(np.float64)
    shown_b = frameless.to_display(frameless.read_image(b)).astype(np.float64)
    want_rms = np.sqrt(((shown_a - shown_b) ** 2).mean())
    got = frameless.metrics.compare(a, b)
    assert got["rms"] == pytest.approx(want_rms, rel=1e-12) and got["rms"] > 0
    assert got["psnr"] == pytest.approx(20 * np.log10(255 / want_rms), rel=1e-12)
    rms_map = frameless.metrics.rms_map(a, b)
    assert np.sqrt((rms_map ** 2).mean()) == pytest.approx(got["rms"], rel=1e-12)
    flip_map = frameless.metrics.flip_map(a, b)
    assert flip_map.shape == (24, 32)
    assert float(flip_map.mean()) == pytest.approx(got["flip"], rel=1e-5) and got["flip"] > 0
    # Arrays and files alike; identical images score zero.
    img = toycar.still(0.5, size=(32, 24), spp=16, progress=False)
    assert frameless.metrics.rms(img, b) == 0 and frameless.metrics.flip(img, img) == 0


def test_progress_leaves_no_stray_lines(toycar, capfd):
    import tqdm  # noqa: F401  (the test extra installs it: the bars are what is tested)

    toycar.still(size=(16, 16), spp=1)
    frameless.evaluate(toycar, methods="adaptive", rates="100k", duration=0.05,
                       size=(16, 16), no_cache=True)
    out, err = capfd.readouterr()
    assert "rows" not in err and "rays" not in err and out == "", (out, err)


@pytest.mark.parametrize("how", ["console script", "python -m"])
def test_the_frameless_command_is_the_binarys(tmp_path, binary, how):
    command = {
        "console script": [str(Path(sys.executable).with_name("frameless"))],
        "python -m": [sys.executable, "-m", "frameless"],
    }[how]
    assert Path(command[0]).is_file(), f"{command[0]}: the package is not installed"

    def run(*args):
        return subprocess.run([*command, *map(str, args)], capture_output=True, text=True)

    scenes = run("scenes")
    assert scenes.returncode == 0, scenes.stderr
    assert scenes.stdout == cli(binary, "scenes").stdout
    args = ["--size", "24x16", "--spp", "2", "--time", "0.25"]
    made = run("still", *args, "-o", tmp_path / "p.png")
    assert made.returncode == 0, made.stderr
    cli(binary, "still", *args, "-o", tmp_path / "b.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "p.png")),
                          np.asarray(Image.open(tmp_path / "b.png")))
    bad = run("still", "--scene", "toycat", "-o", tmp_path / "x.png")
    assert bad.returncode == 1 and "did you mean `toycar`" in bad.stderr, bad.stderr
    assert run("eval", "--bogus").returncode == 2
