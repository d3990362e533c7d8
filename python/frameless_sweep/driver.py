"""Run a frameless sweep on a Dask cluster: one task per shard, then one merge.

Each task runs ``frameless sweep FILE --shard i/N --out RESULTS`` on the worker Dask
gives it; scheduling, placement and retries are Dask's. The shards write their job
results into one folder and share one ideal-image cache, so paths must mean the same
on every worker (a shared file system), and every worker needs the ``frameless``
binary. When all shards are done, ``frameless merge`` runs here.

    python -m frameless_sweep assets/sweeps/example.toml --shards 3 --out example-out
    python -m frameless_sweep SWEEP --shards 64 --scheduler tcp://host:8786 ...
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
import shutil
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Optional, Sequence, Union

PathLike = Union[str, "os.PathLike[str]"]


class ShardFailed(RuntimeError):
    """A ``frameless`` command exited with an error; the message holds its stderr."""


@dataclasses.dataclass(frozen=True)
class ShardOutcome:
    """What one shard's task did, and where."""

    shard: str
    seconds: float
    host: str
    pid: int
    stdout: str


def shard_command(
    binary: PathLike,
    sweep: PathLike,
    index: int,
    count: int,
    results: PathLike,
    *,
    cache_dir: Optional[PathLike] = None,
    bart: Optional[PathLike] = None,
    threads: Optional[int] = None,
) -> list[str]:
    """The command line that runs shard ``index`` of ``count``."""
    cmd = [os.fspath(binary)]
    if threads:
        cmd += ["--threads", str(threads)]
    cmd += ["sweep", os.fspath(sweep), "--shard", f"{index}/{count}", "--out", os.fspath(results)]
    if cache_dir is not None:
        cmd += ["--cache-dir", os.fspath(cache_dir)]
    if bart is not None:
        cmd += ["--bart", os.fspath(bart)]
    return cmd


def _run(cmd: Sequence[str]) -> subprocess.CompletedProcess:
    p = subprocess.run(list(cmd), capture_output=True, text=True)
    if p.returncode != 0:
        raise ShardFailed(f"{shlex.join(cmd)} exited with {p.returncode}:\n{p.stderr.strip()}")
    return p


def run_shard(cmd: Sequence[str]) -> ShardOutcome:
    """Run one shard's command (on a worker); raises ShardFailed if it fails."""
    t0 = time.monotonic()
    p = _run(cmd)
    shard = cmd[list(cmd).index("--shard") + 1]
    return ShardOutcome(shard, time.monotonic() - t0, socket.gethostname(), os.getpid(), p.stdout)


def merge(binary: PathLike, results: Sequence[PathLike], out: PathLike) -> str:
    """``frameless merge RESULTS... --out OUT``; returns what it printed."""
    cmd = [os.fspath(binary), "merge", *map(os.fspath, results), "--out", os.fspath(out)]
    return _run(cmd).stdout


def _absolute(p: Optional[PathLike]) -> Optional[str]:
    # Workers do not share this process's working directory.
    return None if p is None else os.path.abspath(os.fspath(p))


def run_sweep(
    client,
    sweep: PathLike,
    shards: int,
    results: PathLike,
    out: PathLike,
    *,
    binary: PathLike = "frameless",
    cache_dir: Optional[PathLike] = None,
    bart: Optional[PathLike] = None,
    threads: Optional[int] = None,
    retries: int = 0,
) -> list[ShardOutcome]:
    """Submit one task per shard to the Dask ``client``, wait for all, then merge
    the results into ``out``. A failed shard raises ShardFailed (after ``retries``);
    a shard run again keeps the jobs it finished."""
    if shards < 1:
        raise ValueError("shards must be at least 1")
    if os.sep in os.fspath(binary):
        binary = _absolute(binary)
    run_id = uuid.uuid4().hex[:8]
    futures = [
        client.submit(
            run_shard,
            shard_command(
                binary,
                _absolute(sweep),
                i,
                shards,
                _absolute(results),
                cache_dir=_absolute(cache_dir),
                bart=_absolute(bart),
                threads=threads,
            ),
            key=f"frameless-shard-{i}-of-{shards}-{run_id}",
            pure=False,
            retries=retries,
        )
        for i in range(shards)
    ]
    outcomes = client.gather(futures)
    merge(binary, [results], out)
    return outcomes


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m frameless_sweep",
        description="Run a frameless sweep file on a Dask cluster, one task per shard, then merge.",
    )
    ap.add_argument("sweep", help="the sweep file (TOML)")
    ap.add_argument("--shards", type=int, required=True, help="number of shards (tasks)")
    ap.add_argument("--results", default="sweep-results", help="folder of job results, shared by the shards")
    ap.add_argument("--out", default="sweep-out", help="the merged outputs")
    ap.add_argument("--binary", default=shutil.which("frameless") or "frameless", help="the frameless binary, as the workers see it")
    ap.add_argument("--cache-dir", help="ideal-image cache shared by the shards")
    ap.add_argument("--bart", help="BART folder, for scenes named bart:<path>")
    ap.add_argument("--threads", type=int, help="threads per shard (default: all cores of its worker)")
    ap.add_argument("--retries", type=int, default=1, help="times Dask retries a failed shard")
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://host:8786)")
    where.add_argument("--local-workers", type=int, help="start a local cluster of this many workers (default: --shards)")
    a = ap.parse_args(argv)

    try:
        from distributed import Client, LocalCluster
    except ImportError:
        sys.exit("frameless-sweep runs on Dask, which is not installed: "
                 "pip install 'frameless[sweep]'")

    t0 = time.monotonic()
    if a.scheduler:
        client, cluster = Client(a.scheduler), None
    else:
        cluster = LocalCluster(
            n_workers=a.local_workers or a.shards,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
        )
        client = Client(cluster)
    try:
        outcomes = run_sweep(
            client,
            a.sweep,
            a.shards,
            a.results,
            a.out,
            binary=a.binary,
            cache_dir=a.cache_dir,
            bart=a.bart,
            threads=a.threads,
            retries=a.retries,
        )
    except ShardFailed as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    for o in outcomes:
        print(f"shard {o.shard}: {o.seconds:.1f} s on {o.host} (pid {o.pid})")
    print(f"{a.shards} shards and the merge: {time.monotonic() - t0:.1f} s; outputs in {a.out}")
    return 0
