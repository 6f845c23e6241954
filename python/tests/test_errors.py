"""Every error path raises its Python exception, naming the field."""

import json
import signal
import threading
import time

import pytest

import reeb
from conftest import VAN_DER_POL


def scene(**changes):
    s = json.loads(json.dumps(VAN_DER_POL))
    for dotted, value in changes.items():
        *path, key = dotted.split("__")
        d = s
        for p in path:
            d = d[p]
        if value is None:
            del d[key]
        else:
            d[key] = value
    return s


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"model": "van_der_poll"}, "model"),
        ({"params__epsilonn": 1.0}, "params.epsilonn"),
        ({"integrator__dt": -0.1}, "integrator.dt"),
        ({"integrator__scheme": "s3"}, "integrator.scheme"),
        ({"output__final": ["x"]}, "output.final"),
    ],
)
def test_a_bad_scene_raises_scene_error_with_its_field(changes, field):
    with pytest.raises(reeb.SceneError) as e:
        reeb.run(scene(**changes), progress=False)
    assert e.value.field == field, str(e.value)
    assert e.value.line is not None and e.value.message
    with pytest.raises(reeb.SceneError):
        reeb.check(scene(**changes))


def test_a_toml_string_error_names_its_line():
    with pytest.raises(reeb.SceneError) as e:
        reeb.run('model = "van_der_pol"\n[params]\nepsilon = "big"\n', progress=False)
    assert e.value.line == 3 and e.value.field == "params.epsilon"


def test_none_and_missing_files_and_bad_options():
    with_none = scene()
    with_none["params"]["epsilon"] = None
    with pytest.raises(reeb.SceneError) as e:
        reeb.run(with_none, progress=False)
    assert e.value.field == "params.epsilon"
    with pytest.raises(reeb.SceneError):
        reeb.run("no/such/scene.toml", progress=False)
    with pytest.raises(ValueError, match="backend"):
        reeb.run(VAN_DER_POL, backend="tpu", progress=False)
    with pytest.raises(ValueError, match="precision"):
        reeb.run(VAN_DER_POL, precision="f16", progress=False)
    with pytest.raises(reeb.ReebError, match="not a reeb run"):
        reeb.open("no/such/run")


def test_an_existing_foreign_directory_is_refused(tmp_path):
    (tmp_path / "mine.txt").write_text("keep me")
    with pytest.raises(reeb.ReebError, match="--force|force"):
        reeb.run(VAN_DER_POL, out=tmp_path, progress=False)
    assert (tmp_path / "mine.txt").read_text() == "keep me"


def interrupted_after_a_second(work) -> float:
    """Runs `work` with Ctrl-C pressed after 1 s; the seconds it took to end
    in KeyboardInterrupt."""
    # Python's own Ctrl-C handler, as in a terminal or a notebook (a process
    # started in the background inherits SIGINT ignored).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(1.0, signal.raise_signal, (signal.SIGINT,))
    timer.start()
    started = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt):
            work()
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    return time.monotonic() - started


def test_ctrl_c_stops_a_run_within_a_second_and_leaves_nothing_complete(tmp_path):
    # Minutes uninterrupted on any machine (2·10⁹ steps; 2·10⁷ took 12 s
    # once and under 1 s with AVX-512 FMA kernels), Ctrl-C after 1 s.
    long = scene(integrator__steps=2_000_000_000, output={"final": ["q", "s"]})
    out = tmp_path / "long"
    stopped = interrupted_after_a_second(lambda: reeb.run(long, out=out, progress=False))
    assert stopped < 2.5, f"took {stopped:.2f} s to stop"
    assert not out.exists(), "an interrupted run looks complete"
    assert (tmp_path / "long.partial").exists()
    # The interpreter is fine: the next run works.
    assert reeb.run(VAN_DER_POL, progress=False).final_q.size == 15


def test_a_panic_in_the_engine_is_an_internal_error_not_a_crash():
    from reeb import _reeb

    with pytest.raises(reeb.InternalError, match="reeb panicked: lane 7 lost") as e:
        _reeb._panic("lane 7 lost")
    assert isinstance(e.value, reeb.ReebError)
    # The interpreter and the extension go on working.
    assert reeb.check(VAN_DER_POL)["trajectories"] == 15


def test_ctrl_c_stops_a_report_inside_its_run(tmp_path):
    # A stability map whose cells run 10⁹ steps each: minutes uninterrupted.
    long = {
        "name": "long",
        "model": "van_der_pol",
        "params": {"epsilon": {"logspace": [-1.0, 1.0, 2]}},
        "initial": {"q": 2.0},
        "integrator": {"dt": {"logspace": [-4.0, -3.0, 2]}, "t_end": 1e5},
        "output": {"cycle": True},
        "report": {"precisions": ["f64"]},
    }
    out = tmp_path / "map"
    stopped = interrupted_after_a_second(lambda: reeb.report.stability(long, out=out, backend="cpu"))
    assert stopped < 2.5, f"took {stopped:.2f} s to stop"
    # A failed report removes its own `.partial`: nothing is left.
    assert sorted(tmp_path.iterdir()) == [], sorted(tmp_path.iterdir())
