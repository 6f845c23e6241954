"""The examples run (with --preview-sized scenes) and draw their PNGs."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("script", sorted(p.name for p in EXAMPLES.glob("*.py")))
def test_an_example_runs_and_draws(script, tmp_path):
    png = tmp_path / "out.png"
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / script), "--preview", "--out", str(png)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert png.stat().st_size > 10_000, "the picture is nearly empty"


def test_there_are_three_examples():
    assert len(list(EXAMPLES.glob("*.py"))) == 3
