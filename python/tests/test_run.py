"""reeb.run and reeb.open against the `reeb` command: the same arrays,
dimensions, coordinates and attributes, whichever way the scene is given."""

import json

import numpy as np
import pytest
import xarray as xr

import reeb
from conftest import VAN_DER_POL, VAN_DER_POL_TOML, cli


def same_data(a: xr.Dataset, b: xr.Dataset) -> None:
    assert sorted(a.data_vars) == sorted(b.data_vars)
    for name in a.data_vars:
        assert a[name].dims == b[name].dims, name
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
    for name in a.coords:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_dict_toml_and_path_give_the_datasets_of_reeb_run(tmp_path, reeb_cli):
    path = tmp_path / "vdp.toml"
    path.write_text(VAN_DER_POL_TOML)
    cli(reeb_cli, "run", str(path), "--out", str(tmp_path / "cli"))
    expected = reeb.open(tmp_path / "cli")
    for scene in (VAN_DER_POL, VAN_DER_POL_TOML, path, str(path)):
        same_data(reeb.run(scene, progress=False), expected)


def test_the_dataset_is_labelled(tmp_path):
    ds = reeb.run(VAN_DER_POL, progress=False)
    assert ds.final_q.dims == ("epsilon", "q")
    assert ds.trajectory_q.dims == ("epsilon", "q", "frame")
    assert ds.poincare_p.dims == ("epsilon", "q", "point")
    assert ds.sizes == {"epsilon": 5, "q": 3, "frame": 9, "point": 3}
    np.testing.assert_allclose(ds.epsilon.values, np.linspace(0.5, 2.0, 5))
    np.testing.assert_array_equal(ds.q.values, [0.5, 1.5, 2.5])
    assert ds.final_q.dtype == np.float64
    for v in ("cycle_amplitude", "cycle_period", "status", "status_step", "poincare_count"):
        assert v in ds
    assert ds.attrs["backend"] == "cpu"
    assert ds.attrs["traj_steps"] == 15 * 400
    assert ds.attrs["traj_steps_per_s"] > 0
    assert ds.attrs["scene"]["model"] == "van_der_pol"
    assert int(ds.status.sum()) == 0


def test_the_van_der_pol_limit_cycle_has_amplitude_two():
    ds = reeb.run(
        {
            "model": "van_der_pol",
            "params": {"epsilon": [0.5, 1.0, 2.0]},
            "initial": {"q": 0.5},
            "integrator": {"scheme": "triple_jump4", "dt": 0.01, "steps": 6000},
            "output": {"final": ["q"], "cycle": True},
            "run": {"backend": "cpu", "precision": "f64"},
        },
        progress=False,
    )
    np.testing.assert_allclose(ds.cycle_amplitude.values, 2.0, rtol=0.01)
    # The period grows with epsilon (T ≈ 6.66 at epsilon = 1).
    assert ds.cycle_period.sel(epsilon=1.0) == pytest.approx(6.66, rel=0.01)
    assert bool((ds.cycle_period.diff("epsilon") > 0).all())


def test_results_reach_numpy_without_a_copy():
    ds = reeb.run(VAN_DER_POL, progress=False)
    q = ds.final_q.values
    # The run's own array, memory-mapped (its directory is already gone).
    base = q
    while not isinstance(base, np.memmap) and getattr(base, "base", None) is not None:
        base = base.base
    assert isinstance(base, np.memmap), type(base)
    assert q.flags.writeable
    q[0, 0] = 42.0
    assert ds.final_q.values[0, 0] == 42.0


def test_numpy_arrays_are_accepted_where_lists_are():
    scene = json.loads(json.dumps(VAN_DER_POL))
    scene["initial"]["q"] = np.array([0.5, 1.5, 2.5])
    scene["integrator"]["steps"] = np.int64(400)
    same_data(reeb.run(scene, progress=False), reeb.run(VAN_DER_POL, progress=False))


def test_out_writes_the_run_as_reeb_run_does(tmp_path, reeb_cli):
    ds = reeb.run(VAN_DER_POL, out=tmp_path / "py", progress=False)
    path = tmp_path / "vdp.toml"
    path.write_text(VAN_DER_POL_TOML)
    cli(reeb_cli, "run", str(path), "--out", str(tmp_path / "cli"))
    files = lambda d: sorted(p.name for p in d.iterdir())
    assert files(tmp_path / "py") == files(tmp_path / "cli")
    for f in (tmp_path / "cli").glob("*.npy"):
        assert (tmp_path / "py" / f.name).read_bytes() == f.read_bytes(), f.name
    same_data(ds, reeb.open(tmp_path / "cli"))


def test_the_keywords_of_run_are_the_options_of_reeb_run(tmp_path, reeb_cli):
    """One definition (issue 35, point 5): reeb.run's keywords are reeb
    run's flags, checked against the list the engine's own parser gives."""
    import inspect

    names = set(reeb.run_options())
    assert {"backend", "precision", "out", "force", "resume", "format", "chunk_trajectories", "checkpoint_every", "adapter"} <= names
    explicit = set(inspect.signature(reeb.run).parameters) - {"scene", "progress", "preview", "options"}
    assert explicit <= names, explicit - names
    help_text = cli(reeb_cli, "run", "--help")
    for n in names:
        assert "--" + n.replace("_", "-") in help_text, n
    # Options only a keyword reaches: the chunk size changes the chunks, not the values.
    chunked = reeb.run(VAN_DER_POL, out=tmp_path / "chunked", chunk_trajectories=3, progress=False)
    same_data(chunked, reeb.run(VAN_DER_POL, progress=False))
    assert json.loads((tmp_path / "chunked" / "summary.json").read_text())["chunks"]["trajectories"] == 3
    with pytest.raises(TypeError, match="colour"):
        reeb.run(VAN_DER_POL, colour="red", progress=False)
    with pytest.raises(ValueError, match="^chunk_trajectories: "):
        reeb.run(VAN_DER_POL, chunk_trajectories=0, progress=False)
    with pytest.raises(ValueError, match="^shard: "):
        reeb.run(VAN_DER_POL, shard="0/2", progress=False)


def test_a_zarr_run_opens_lazily_with_the_same_values(tmp_path):
    scene = json.loads(json.dumps(VAN_DER_POL))
    scene["output"]["format"] = "zarr"
    ds = reeb.run(scene, out=tmp_path / "z", progress=False)
    assert (tmp_path / "z" / "run.zarr").is_dir()
    assert ds.final_q.chunks is not None  # dask-backed: read when asked
    same_data(ds.load(), reeb.run(VAN_DER_POL, progress=False))


def test_a_vector_output_has_a_component_dimension():
    ds = reeb.run(
        {
            "model": "kepler",
            "params": {"alpha": 0.01},
            "initial": {"eccentricity": [0.1, 0.5]},
            "integrator": {"scheme": "s2", "dt": 0.01, "steps": 100},
            "output": {"final": ["q"]},
            "run": {"backend": "cpu"},
        },
        progress=False,
    )
    assert ds.final_q.dims == ("eccentricity", "component")
    assert ds.sizes["component"] == 2


def test_check_info_and_verify():
    c = reeb.check(VAN_DER_POL)
    assert c["trajectories"] == 15 and c["axes"] == ["epsilon", "q"] and c["plans"] == 1
    assert c["output_bytes"] > 0
    i = reeb.info()
    assert i["version"] == reeb.__version__ and i["cpu"]["threads"] >= 1
    rows = reeb.verify(backend="cpu", precision="f64")
    assert len(rows) > 20
    failed = [r for r in rows if not r["pass"]]
    assert not failed, failed


def test_stops_averages_and_resonances_reach_the_dataset():
    ds = reeb.run(
        {
            "model": "damped_oscillator",
            "params": {"alpha": [0.05, 0.6]},
            "initial": {"q": {"linspace": [-2.0, 2.0, 8]}, "p": 0.3},
            "integrator": {"scheme": "s2", "dt": 0.05, "steps": 600},
            "output": {
                "final": ["q", "t"],
                "trajectory": {"every": 1, "vars": ["p"]},
                "average": {"vars": ["p"], "skip": 0.0},
                "resonance": {"var": "p", "ratios": [[1, 40]], "tolerance": 0.03},
                "stop": "t > 20.52 + 20*alpha",
            },
            "run": {"backend": "cpu", "precision": "f64"},
        },
        progress=False,
    )
    assert ds.mean_p.dims == ("alpha", "q")
    assert ds.resonance.dims == ("alpha", "q")
    assert ds.resonance.dtype == np.int32
    # α = 0.05 stops after t > 21.52 (step 431), α = 0.6 runs to the end.
    np.testing.assert_array_equal(ds.status.sel(alpha=0.05), 2)
    np.testing.assert_array_equal(ds.status_step.sel(alpha=0.05), 431)
    np.testing.assert_array_equal(ds.status.sel(alpha=0.6), 0)
    np.testing.assert_array_equal(ds.status_step.sel(alpha=0.6), -1)
    np.testing.assert_allclose(ds.final_t.sel(alpha=0.05), 431 * 0.05)
    # The mean is the plain mean of the steps 1 … last.
    last = np.where(ds.status == 2, ds.status_step, 600)
    p = ds.trajectory_p.values
    for i in range(2):
        for j in range(8):
            plain = p[i, j, 1 : last[i, j] + 1].mean()
            assert ds.mean_p.values[i, j] == pytest.approx(plain, rel=1e-12, abs=1e-15)
    captured = np.abs(ds.mean_p.values - 1 / 40) <= 0.03
    np.testing.assert_array_equal(ds.resonance.values, np.where(captured, 0, -1))
    fractions = ds.attrs["capture_fractions"]
    assert fractions["1:40"] == pytest.approx(captured.mean())
    assert fractions["none"] == pytest.approx(1 - captured.mean())
    assert ds.attrs["status"]["stopped"] == 8


def test_chaos_indicators_reach_the_dataset():
    ds = reeb.run(
        {
            "model": "damped_oscillator",
            "params": {"alpha": [0.1, 0.4]},
            "initial": {"q": {"linspace": [-1.0, 1.0, 3]}},
            "integrator": {"scheme": "triple_jump4", "dt": 0.05, "steps": 400},
            "output": {
                "final": ["q"],
                "trajectory": {"every": 40, "vars": ["q"]},
                "lyapunov": {"vectors": 2, "every": 4},
                "fli": True,
                "megno": True,
            },
            "run": {"backend": "cpu", "precision": "f64"},
        },
        progress=False,
    )
    assert ds.lyapunov.dims == ("alpha", "q", "exponent")
    assert ds.fli.dims == ds.megno.dims == ("alpha", "q")
    # The step scales (q, p) areas by e^{−α dt}: λ₁ + λ₂ = −α, λ₁ ≥ λ₂.
    total = ds.lyapunov.sum("exponent")
    np.testing.assert_allclose(total, -ds.alpha.broadcast_like(total), rtol=1e-10)
    assert (ds.lyapunov.isel(exponent=0) >= ds.lyapunov.isel(exponent=1)).all()
    assert np.isfinite(ds.fli).all() and np.isfinite(ds.megno).all()
    # Running values per trajectory frame, ending at the outputs.
    assert ds.trajectory_lyapunov.dims == ("alpha", "q", "frame", "exponent")
    assert ds.trajectory_fli.dims == ds.trajectory_megno.dims == ("alpha", "q", "frame")
    last = {"frame": -1}
    np.testing.assert_array_equal(ds.trajectory_lyapunov.isel(last), ds.lyapunov)
    np.testing.assert_array_equal(ds.trajectory_fli.isel(last), ds.fli)
    np.testing.assert_array_equal(ds.trajectory_megno.isel(last), ds.megno)
    assert np.isnan(ds.trajectory_fli.isel(frame=0)).all()
