"""ColorVideoVDP's JOD (frameless.vdp, the extra `frameless[vdp]`) on a tiny video.

Skipped, with its reason, where `cvvdp` is not installed: `.ci/run` installs
`./python[test]` only, since PyTorch from PyPI is about 5.7 GB (docs/python.md). Run
it with `pip install './python[test,vdp]'`. Needs the frameless binary for the folder
test: $FRAMELESS_BIN, else target/release/frameless.
"""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import frameless

pytest.importorskip(
    "pycvvdp", reason="needs ColorVideoVDP: pip install 'frameless[vdp]' (PyTorch, ~5.7 GB)")

from frameless import vdp  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def test_identical_videos_score_ten_and_noise_scores_less():
    rng = np.random.default_rng(1)
    ref = (rng.random((8, 32, 48, 3)) * 255).astype(np.uint8)
    noisy = np.clip(ref.astype(int) + rng.integers(-30, 31, ref.shape), 0, 255).astype(np.uint8)
    assert vdp.video_jod(ref, ref, 60.0) == pytest.approx(10.0, abs=1e-4)
    assert vdp.video_jod(noisy, ref, 60.0) < 9.9
    with pytest.raises(ValueError, match="same"):
        vdp.video_jod(ref[:4], ref, 60.0)
    with pytest.raises(ValueError, match="uint8"):
        vdp.video_jod(ref.astype(np.float32), ref.astype(np.float32), 60.0)


def test_each_channel_alone_scores_at_least_the_whole_and_flicker_is_transient():
    rng = np.random.default_rng(2)
    still = np.repeat((rng.random((1, 32, 48, 3)) * 255).astype(np.uint8), 12, axis=0)
    same = vdp.video_jod_parts(still, still, 60.0)
    assert same["jod"] == pytest.approx(10.0, abs=1e-4)
    assert set(same["parts"]) == set(vdp.CHANNELS)
    assert all(j == pytest.approx(10.0, abs=1e-4) for j in same["parts"].values())
    # A grey flicker on every other frame: the achromatic transient channel is where
    # the difference is, so it alone scores lowest, and no channel alone below the whole.
    flicker = still.astype(int)
    flicker[1::2] += 40
    flicker = np.clip(flicker, 0, 255).astype(np.uint8)
    got = vdp.video_jod_parts(flicker, still, 60.0)
    parts = got["parts"]
    assert all(j >= got["jod"] - 1e-4 for j in parts.values()), got
    assert min(parts, key=parts.get) == "achromatic_transient", got
    assert vdp.video_jod(flicker, still, 60.0) == pytest.approx(got["jod"])


def test_evaluate_gives_every_row_a_jod_of_the_images_it_scored():
    ev = frameless.evaluate("toycar", methods=["adaptive", "traditional-frameless"],
                            rates=["100k"], duration=0.1, size=(48, 32), ideal_spp=2,
                            progress=False, video_metric="cvvdp")
    for r in ev.results:
        assert r["jod"] < 10.0, r  # no method shows exactly the ideal video
        assert r["jod_display"] == vdp.DEFAULT_DISPLAY
    with pytest.raises(ValueError, match="cvvdp"):
        frameless.evaluate("toycar", video_metric="vmaf")


def test_a_folder_gets_vdp_json_and_a_wrong_scene_is_refused(tmp_path):
    binary = Path(os.environ.get("FRAMELESS_BIN") or REPO / "target" / "release" / "frameless")
    if not binary.is_file():
        pytest.fail(f"no frameless binary at {binary}: run `cargo build` or set FRAMELESS_BIN")
    out = tmp_path / "ev"
    subprocess.run([str(binary), "eval", "--scene", "toycar", "--method", "adaptive",
                    "--rate", "100k", "--duration", "0.1", "--size", "48x32",
                    "--ideal-spp", "2", "--no-cache", "--out", str(out)],
                   check=True, capture_output=True)
    path = vdp.add_to_folder(out, "toycar")
    rows = json.loads(path.read_text())["results"]
    assert [r["method"] for r in rows] == ["adaptive"] and rows[0]["jod"] < 10.0
    report = subprocess.run([str(binary), "report", str(out)], check=True,
                            capture_output=True, text=True)
    assert "Video JOD" in (out / "report.html").read_text(), report.stderr
    # Another scene's images are not the evaluation's: refused, not scored.
    with pytest.raises(ValueError, match="not the evaluation's"):
        vdp.add_to_folder(out, "room")
