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
