"""The Dask driver runs assets/sweeps/example.toml as three tasks on a local cluster
(worker processes on this machine) and merges; the outputs are those of the sweep run
as one shard by the binary directly: byte for byte, except summary.json's "timing"
objects (wall-clock seconds, summed over jobs) and report.html, which prints them.

Needs the frameless binary: $FRAMELESS_BIN, else target/release/frameless (cargo build --release).
"""

import os
import re
import subprocess
from pathlib import Path

import pytest
from distributed import Client, LocalCluster

from frameless_sweep import ShardFailed, run_sweep

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "assets" / "sweeps" / "example.toml"


@pytest.fixture(scope="module")
def binary() -> Path:
    p = Path(os.environ.get("FRAMELESS_BIN") or REPO / "target" / "release" / "frameless")
    if not p.is_file():
        pytest.fail(f"no frameless binary at {p}: run `cargo build` or set FRAMELESS_BIN")
    return p


@pytest.fixture(scope="module")
def client():
    with LocalCluster(
        n_workers=3, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as c:
        yield c


def tree(root: Path) -> dict:
    return {p.relative_to(root): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def without_timing(data: bytes) -> str:
    text, n = re.subn(r'"timing": \{[^}]*\}', '"timing": {}', data.decode())
    assert n > 0, "a summary has timing sections"
    return text


def test_three_dask_tasks_merge_to_the_single_run(tmp_path, binary, client):
    outcomes = run_sweep(
        client,
        EXAMPLE,
        3,
        tmp_path / "results",
        tmp_path / "merged",
        binary=binary,
        cache_dir=tmp_path / "cache",
        threads=1,
    )
    assert sorted(o.shard for o in outcomes) == ["0/3", "1/3", "2/3"]
    # The tasks ran in the cluster's worker processes, not in this one.
    assert all(o.pid != os.getpid() for o in outcomes)
    assert len(list((tmp_path / "results").glob("*.json"))) == 7

    ref_results = tmp_path / "ref-results"
    ref = tmp_path / "ref"
    for cmd in (
        [binary, "sweep", EXAMPLE, "--out", ref_results, "--cache-dir", tmp_path / "ref-cache"],
        [binary, "merge", ref_results, "--out", ref],
    ):
        subprocess.run([str(c) for c in cmd], check=True, capture_output=True)

    got, want = tree(tmp_path / "merged"), tree(ref)
    assert sorted(got) == sorted(want)
    compared = 0
    for rel, data in want.items():
        if rel.name == "report.html":
            continue
        if rel.name == "summary.json":
            assert without_timing(got[rel]) == without_timing(data), rel
        else:
            assert got[rel] == data, rel
        compared += 1
    assert compared >= 5


def test_a_failed_shard_names_its_command(tmp_path, binary, client):
    with pytest.raises(ShardFailed) as e:
        run_sweep(client, tmp_path / "no-such.toml", 2, tmp_path / "r", tmp_path / "o", binary=binary)
    assert "--shard" in str(e.value) and "no-such.toml" in str(e.value)
