"""The example notebooks run top to bottom in a Jupyter kernel, every cell
without error, and draw their figures. CI sets REEB_REQUIRE_NOTEBOOK=1, so
that a missing nbclient fails instead of skipping."""

import os
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

if os.environ.get("REEB_REQUIRE_NOTEBOOK") == "1":
    import nbclient
    import nbformat
else:
    nbclient = pytest.importorskip("nbclient")
    nbformat = pytest.importorskip("nbformat")


def test_chaos_maps_notebook_runs(tmp_path):
    nb = nbformat.read(EXAMPLES / "chaos_maps.ipynb", as_version=4)
    client = nbclient.NotebookClient(
        nb,
        timeout=600,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    client.execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    figures = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(figures) == 5, f"{len(figures)} figures"
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "all checks passed" in text
