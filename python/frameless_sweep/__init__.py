"""Run a frameless evaluation sweep on a Dask cluster (see ``driver``)."""

from .driver import ShardFailed, ShardOutcome, merge, run_shard, run_sweep, shard_command

__all__ = ["ShardFailed", "ShardOutcome", "merge", "run_shard", "run_sweep", "shard_command"]
