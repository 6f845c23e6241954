"""Shared fixtures: small scenes, and the `reeb` command the Datasets are
compared with."""

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def reeb_cli() -> Path:
    """The `reeb` binary (REEB_BIN, else the repository's release build)."""
    path = Path(os.environ.get("REEB_BIN", REPO / "target" / "release" / "reeb"))
    if not path.is_file():
        pytest.fail(f"no reeb binary at {path}: cargo build --release, or set REEB_BIN")
    return path


def cli(reeb_cli: Path, *args: str) -> str:
    done = subprocess.run([str(reeb_cli), *args], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done.stdout + done.stderr


VAN_DER_POL = {
    "name": "vdp",
    "model": "van_der_pol",
    "params": {"epsilon": {"linspace": [0.5, 2.0, 5]}},
    "initial": {"q": [0.5, 1.5, 2.5]},
    "integrator": {"scheme": "s2", "dt": 0.01, "steps": 400},
    "output": {
        "final": ["q", "s"],
        "trajectory": {"every": 50, "vars": ["q"]},
        "poincare": {"period": 1.0, "vars": ["q", "p"], "max_points": 3},
        "cycle": True,
    },
    "run": {"backend": "cpu", "precision": "f64"},
}

VAN_DER_POL_TOML = """name = "vdp"
model = "van_der_pol"
[params]
epsilon = { linspace = [0.5, 2.0, 5] }
[initial]
q = [0.5, 1.5, 2.5]
[integrator]
scheme = "s2"
dt = 0.01
steps = 400
[output]
final = ["q", "s"]
trajectory = { every = 50, vars = ["q"] }
poincare = { period = 1.0, vars = ["q", "p"], max_points = 3 }
cycle = true
[run]
backend = "cpu"
precision = "f64"
"""
