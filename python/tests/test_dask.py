"""reeb.dask.run on a LocalCluster: shards on two workers, one Zarr store,
bitwise the single-process run."""

import distributed

import reeb
from conftest import VAN_DER_POL


def test_shards_on_a_local_cluster_give_the_bits_of_one_process(tmp_path):
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            ds = reeb.dask.run(VAN_DER_POL, client, shards=4, store=tmp_path / "store")
    assert (tmp_path / "store" / "run.zarr").is_dir()
    assert ds.attrs["chunks"]["count"] >= 4
    one = reeb.run(VAN_DER_POL, progress=False)
    assert sorted(ds.data_vars) == sorted(one.data_vars)
    for name in one.data_vars:
        a, b = ds[name].values, one[name].values
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
    assert ds.final_q.dims == ("epsilon", "q")


def test_a_failed_shard_run_again_resumes_its_finished_chunks(tmp_path, capfd):
    """What a Dask retry does: the same shard called again after a failure
    halfway continues from its finished chunks, and the merged store is
    bitwise the single-process run."""
    from reeb import _reeb
    from reeb._scene import resolve

    scene = {**VAN_DER_POL, "integrator": {"scheme": "s2", "dt": 0.002, "steps": 250_000}}
    scene["output"] = {"final": ["q", "s"], "cycle": True}
    text, path = resolve(scene)
    store = str(tmp_path / "store")
    options = dict(format="zarr", chunk_trajectories=3)

    def lost_halfway(done, total):
        if done > total // 2:
            raise RuntimeError("worker lost")

    try:
        _reeb.run(text, path, store, shard="0/1", resume=True, progress=lost_halfway, **options)
    except RuntimeError as e:
        assert "worker lost" in str(e)
    else:
        raise AssertionError("the shard finished before it failed")
    capfd.readouterr()
    reeb.dask._shard(text, path, store, 0, 1, options)
    said = capfd.readouterr().err
    assert "resuming:" in said and "already finished" in said, said
    _reeb.merge(store)
    ds = reeb.open(store)
    one = reeb.run(scene, progress=False)
    for name in one.data_vars:
        assert ds[name].values.tobytes() == one[name].values.tobytes(), name


def test_a_worker_killed_mid_shard_is_retried_and_resumes(tmp_path, capfd):
    """A worker process SIGKILLed while its shard runs: the nanny restarts
    it, the scheduler runs the shard again, the shard continues from the
    chunks finished before the kill, and the store is bitwise the
    single-process run."""
    import os
    import signal
    import threading
    import time

    scene = {**VAN_DER_POL, "integrator": {"scheme": "s2", "dt": 0.002, "steps": 500_000}}
    scene["output"] = {"final": ["q", "s"], "cycle": True}
    store = tmp_path / "store"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            pids = client.run(os.getpid)
            result = {}

            def shards():
                try:
                    result["ds"] = reeb.dask.run(scene, client, shards=1, store=store, chunk_trajectories=3)
                except BaseException as e:  # noqa: BLE001 - handed to the test thread
                    result["error"] = e

            running = threading.Thread(target=shards)
            running.start()
            deadline = time.monotonic() + 120
            while not list(tmp_path.glob("store.partial/**/.reeb-chunks/*.json")):
                assert time.monotonic() < deadline and running.is_alive(), result
                time.sleep(0.05)
            busy = [w for w, tasks in client.processing().items() if tasks]
            assert len(busy) == 1, client.processing()
            os.kill(pids[busy[0]], signal.SIGKILL)
            running.join(timeout=300)
            assert not running.is_alive()
    assert "error" not in result, result.get("error")
    said = capfd.readouterr().err
    assert "already finished" in said, said
    one = reeb.run(scene, progress=False)
    for name in one.data_vars:
        assert result["ds"][name].values.tobytes() == one[name].values.tobytes(), name
