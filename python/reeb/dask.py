"""Runs one scene's shards on the workers of a Dask cluster.

    >>> from distributed import Client
    >>> client = Client()            # or a dask-jobqueue SLURMCluster, PBSCluster, …
    >>> ds = reeb.dask.run("scene.toml", client, shards=16, store="/scratch/run")

Each shard is ``reeb run SCENE --out STORE --shard K/N --resume`` on a
worker, writing its own chunks of one Zarr store (``STORE/run.zarr``); a
failed worker's shard is retried and continues from its finished chunks
and checkpoints. The merged store is bitwise identical to a run in one
process.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Optional

from . import _reeb
from ._api import PathLike, open
from ._scene import Scene, resolve


def _shard(text: str, path: str, store: str, k: int, n: int, options: dict) -> str:
    """One shard, on a worker (a top-level function: Dask pickles it)."""
    return _reeb.run(text, path, store, shard=f"{k}/{n}", resume=True, progress=None, **options)


def run(
    scene: Scene,
    client: Any,
    *,
    shards: int,
    store: PathLike,
    backend: Optional[str] = None,
    precision: Optional[str] = None,
    chunk_trajectories: Optional[int] = None,
    retries: int = 3,
):
    """Integrates ``scene`` as ``shards`` tasks on ``client``'s workers
    (``distributed.Client``) into the Zarr store in ``store`` (a directory
    every worker can write: a shared filesystem on a cluster), merges it,
    and returns it opened lazily (``reeb.open``). By default the ensemble
    is cut into at least ``shards`` chunks, so every task has work."""
    if shards < 1:
        raise ValueError(f"shards: {shards} (at least 1)")
    text, path = resolve(scene)
    if chunk_trajectories is None:
        n = json.loads(_reeb.check(text, path, precision=precision))["trajectories"]
        chunk_trajectories = max(1, -(-n // shards))
    options = dict(
        backend=backend,
        precision=precision,
        format="zarr",
        chunk_trajectories=chunk_trajectories,
    )
    out = str(Path(store).resolve())
    futures = client.map(
        _shard,
        [text] * shards,
        [path] * shards,
        [out] * shards,
        range(shards),
        [shards] * shards,
        [options] * shards,
        retries=retries,
        pure=False,
    )
    client.gather(futures)
    _reeb.merge(out)
    return open(out)
