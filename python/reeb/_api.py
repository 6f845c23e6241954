"""``reeb.run``, ``reeb.open``, ``reeb.check``, ``reeb.verify``, ``reeb.info``."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

from . import _reeb
from ._scene import Scene, resolve
from .errors import ReebError

PathLike = Union[str, "os.PathLike[str]"]


class _Bar:
    """A tqdm bar (it renders in Jupyter too) fed ``(done, total)``
    trajectory-steps; nothing when ``enabled`` is false."""

    def __init__(self, enabled: bool, desc: str) -> None:
        self.enabled, self.desc, self.bar = enabled, desc, None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or total == 0:
            return
        if self.bar is None:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc=self.desc, unit="traj-step", unit_scale=True)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run(
    scene: Scene,
    *,
    backend: Optional[str] = "auto",
    precision: Optional[str] = None,
    out: Optional[PathLike] = None,
    progress: bool = True,
    force: bool = False,
    preview: bool = False,
    checkpoint_every: Optional[float] = None,
    **options: Any,
):
    """Integrates ``scene`` and returns its outputs as an ``xarray.Dataset``.

    ``scene`` is a path, a TOML string, or a dict with the TOML's structure
    (numpy arrays wherever a list is). ``backend`` is ``"auto"`` (a hardware
    GPU if there is one, else every CPU core), ``"cpu"``, ``"gpu"``, or
    ``None`` (the scene's ``[run] backend``, as without ``--backend``);
    ``precision`` ``"f32"`` or ``"f64"`` overrides the scene's. With ``out``
    the run is also written to that directory exactly as ``reeb run`` writes
    it (``force`` replaces a directory holding files reeb did not write;
    ``checkpoint_every`` seconds between checkpoints, as ``--checkpoint-every``)
    and the Dataset reads it (lazily for a Zarr store); without ``out`` the
    run goes to a temporary directory, removed before this returns, whose
    arrays the Dataset keeps memory-mapped (copy-on-write: no copy; the
    memory is freed with the Dataset; a Zarr-format scene is read into
    memory instead). ``preview``: at most 4 values per axis and 2000
    steps. ``progress``: a tqdm bar over trajectory-steps.

    Every other option of ``reeb run`` is a keyword too, spelt as its flag
    with ``_`` for ``-`` (``reeb.run_options()`` lists them):
    ``chunk_trajectories=N``, ``format="zarr"``, ``resume=True`` (with
    ``out``), ``adapter=K``; ``shard`` is for ``reeb.dask.run`` and
    ``reeb run --shard``, since a shard is not a whole run.

    The GIL is released while the engine runs; Ctrl-C stops the run within a
    second and raises ``KeyboardInterrupt`` (a run into ``out`` then leaves
    ``out.partial``, which ``reeb run --resume`` continues, never ``out``).
    Errors raise ``reeb.SceneError`` (with ``.field``, ``.line``,
    ``.message``) or ``reeb.ReebError``.
    """
    if "shard" in options:
        raise ValueError("shard: reeb.run returns a whole run; run shards with reeb.dask.run, or reeb run --shard K/N and reeb merge")
    text, path = resolve(scene)
    temporary = None
    if out is None:
        temporary = tempfile.mkdtemp(prefix="reeb-")
        target = Path(temporary) / "run"
    else:
        target = Path(out)
    bar = _Bar(progress, "reeb")
    try:
        _reeb.run(
            text,
            path,
            str(target),
            backend=backend,
            precision=precision,
            force=force,
            preview=preview,
            checkpoint_every=checkpoint_every,
            progress=bar,
            **options,
        )
        bar.close()
        ds = open(target)
        if temporary is not None and (target / "run.zarr").exists():
            ds = ds.load()  # the store goes with the temporary directory
        return ds
    finally:
        bar.close()
        if temporary is not None:
            shutil.rmtree(temporary, ignore_errors=True)


def open(path: PathLike, *, memory_map: bool = True):
    """A run directory (``.npy`` files or a Zarr store) as the Dataset
    ``reeb.run`` returns: a Zarr store lazily (dask arrays), ``.npy`` files
    memory-mapped copy-on-write (no copy; writable, never written back;
    ``memory_map=False``: read into memory)."""
    import numpy as np
    import xarray as xr

    d = Path(path)
    summary_file = d / "summary.json"
    if not summary_file.is_file():
        partial = d.with_name(d.name + ".partial")
        if partial.exists():
            raise ReebError(
                f"{d} is not a finished run: {partial} holds one in progress "
                f"(continue it with reeb run SCENE --out {d} --resume, or reeb merge {d} after shards)"
            )
        raise ReebError(f"{d} is not a reeb run directory (no summary.json)")
    summary = json.loads(summary_file.read_text())
    attrs = _attributes(summary)
    table = d / "attractors.json"
    if table.is_file():
        attrs["attractor_table"] = json.loads(table.read_text())
    if (d / "run.zarr").exists():
        ds = xr.open_zarr(d / "run.zarr", consolidated=False)
        ds.attrs = attrs
        return ds
    axes = [a["name"] for a in summary["scene"]["axes"]]
    mode = "c" if memory_map else None
    coords = {a: np.load(d / f"axis_{a}.npy") for a in axes}
    data = {}
    for f in summary["files"]:
        if not f.endswith(".npy") or f.startswith("axis_"):
            continue
        name = f[: -len(".npy")]
        values = np.load(d / f, mmap_mode=mode)
        data[name] = (_dims(summary, name, axes, values.ndim), values)
    return xr.Dataset(data, coords=coords, attrs=attrs)


def attractors(run) -> "pandas.DataFrame":
    """The attractors of a run with ``output.attractors`` (a Dataset from
    ``reeb.run``/``reeb.open``, or a run directory) as a DataFrame, one row
    per attractor by label (escapes as −1): its ``kind`` (``fixed_point``,
    ``periodic``, ``aperiodic``, ``escape``), ``period``, ``count``,
    ``fraction`` and ``fraction_error``, ``lyapunov`` and ``chaotic`` where
    the run has exponents, the parameter values it was found between along a
    continued axis (``found_from``, ``found_to``), and its sample points, a
    column ``points_<variable>`` of lists."""
    try:
        import pandas as pd
    except ImportError as e:
        raise ReebError("reeb.attractors needs pandas (pip install pandas)") from e

    ds = run if hasattr(run, "attrs") else open(run)
    table = ds.attrs.get("attractor_table")
    if table is None:
        raise ReebError("the run has no attractors: its scene has no output.attractors")
    rows = []
    for entry in table:
        row = {k: v for k, v in entry.items() if k != "points"}
        for var, values in entry.get("points", {}).items():
            row[f"points_{var}"] = values
        rows.append(row)
    return pd.DataFrame(rows).set_index("label")


def _dims(summary: Dict[str, Any], name: str, axes: List[str], ndim: int) -> List[str]:
    """The dimension names of array ``name``: those summary.json lists, or
    (runs written before it listed them) the scene's axes, then ``frame``
    or ``point``, then ``component``."""
    listed = summary.get("dims", {}).get(name)
    if listed is not None:
        return listed
    inner = {"trajectory": ["frame"], "poincare": ["point"]}.get(name.split("_")[0], [])
    if name == "poincare_count":
        inner = []
    extra = ndim - len(axes) - len(inner)
    return axes + inner + ["component"] * extra


def _attributes(summary: Dict[str, Any]) -> Dict[str, Any]:
    """The Dataset's attributes: the summary, the resolved scene in it, and
    with ``output.resonance`` the fraction of the ensemble captured in each
    ratio (and ``"none"``) as ``capture_fractions``."""
    attrs = dict(summary)
    if "resonance" in summary:
        attrs["capture_fractions"] = dict(summary["resonance"]["fractions"])
    return attrs


def check(scene: Scene, *, precision: Optional[str] = None, out: Optional[PathLike] = None) -> Dict[str, Any]:
    """Every gate of ``reeb.run`` without running (the scene, its sizes, the
    output directory's refusals): returns the model, scheme, precision,
    trajectories, axes, plans, estimated output bytes and warnings; raises
    ``reeb.SceneError`` or ``reeb.ReebError`` as ``run`` would."""
    text, path = resolve(scene)
    return json.loads(_reeb.check(text, path, precision=precision, out=None if out is None else str(out)))


def verify(*, backend: str = "cpu", precision: str = "f64") -> List[Dict[str, Any]]:
    """``reeb verify``: every model's oracle and every scheme's measured
    order on ``backend`` in ``precision``; one dict per check (``check``,
    ``pass``, ``expected``, ``measured``, ``tolerance``)."""
    return json.loads(_reeb.verify(backend, precision))


def run_options() -> List[str]:
    """The keywords of ``reeb.run`` that are ``reeb run``'s options (its
    flags, ``_`` for ``-``)."""
    return list(_reeb.run_option_names())


def info() -> Dict[str, Any]:
    """``reeb info``: the version, the CPU's kernels and threads, the GPU
    adapters with their limits, and what ``--backend gpu`` would use."""
    return json.loads(_reeb.info())

