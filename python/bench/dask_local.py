"""reeb.dask.run on a LocalCluster (2 workers × 1 thread) against reeb.run
in one process, on the same scene: 65,536 van der Pol trajectories × 10⁵ S2
steps (f32, final q and s, Zarr). Wall time of each, and whether the arrays
are bitwise equal.

    python dask_local.py [--shards 4]
"""

import argparse
import tempfile
import time
from pathlib import Path

import distributed

import reeb

SCENE = {
    "name": "dask_local",
    "model": "van_der_pol",
    "params": {"epsilon": {"linspace": [0.1, 3.0, 256]}},
    "initial": {"q": {"linspace": [0.5, 2.5, 256]}},
    "integrator": {"scheme": "s2", "dt": 0.01, "steps": 100_000},
    "output": {"final": ["q", "s"], "format": "zarr"},
    "run": {"backend": "cpu", "precision": "f32"},
}

if __name__ == "__main__":
    args = argparse.ArgumentParser()
    args.add_argument("--shards", type=int, default=4)
    a = args.parse_args()
    work = Path(tempfile.mkdtemp())
    t = time.perf_counter()
    one = reeb.run(SCENE, out=work / "one", progress=False)
    single = time.perf_counter() - t
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            t = time.perf_counter()
            ds = reeb.dask.run(SCENE, client, shards=a.shards, store=work / "dask")
            sharded = time.perf_counter() - t
    same = all(ds[v].values.tobytes() == one[v].values.tobytes() for v in one.data_vars)
    print(f"one process: {single:.2f} s; reeb.dask.run, {a.shards} shards on 2 workers: {sharded:.2f} s "
          f"(ratio {sharded / single:.2f}); bitwise equal: {same}")
