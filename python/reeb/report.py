"""reeb's reports from Python: ``work_precision`` (error against run time
for every scheme, and the measured orders) and ``stability`` (the class and
error maps over a scene's two axes). Each writes the same directory as
``reeb report`` and returns its table and pictures."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, List, NamedTuple, Optional

from . import _reeb
from ._api import PathLike
from ._scene import Scene, resolve


class Report(NamedTuple):
    """A report: its table (a pandas DataFrame, or a list of row dicts
    without pandas), its pictures (PNG paths) and its directory."""

    table: Any
    pictures: List[Path]
    dir: Path


def _report(kind: str, scene: Scene, out, backend, precision, force) -> Report:
    text, path = resolve(scene)
    written = Path(
        _reeb.report(
            kind,
            text,
            path,
            out=None if out is None else str(out),
            backend=backend,
            precision=precision,
            force=force,
        )
    )
    # Every point of the report, one line each.
    table = written.parent / f"{kind.replace('-', '_')}.csv"
    try:
        import pandas

        rows: Any = pandas.read_csv(table)
    except ImportError:
        with table.open(newline="") as f:
            rows = list(csv.DictReader(f))
    return Report(rows, sorted(table.parent.glob("*.png")), table.parent)


def work_precision(
    scene: Scene,
    *,
    out: Optional[PathLike] = None,
    backend: Optional[str] = None,
    precision: Optional[str] = None,
    force: bool = False,
) -> Report:
    """The work–precision report of ``scene`` (``reeb report
    work-precision``): every scheme of its ``[report]`` over its range of
    ``dt``, error against a DOP853 or closed-form reference and run time,
    in ``out`` (default ``runs/<name>-work-precision``)."""
    return _report("work-precision", scene, out, backend, precision, force)


def stability(
    scene: Scene,
    *,
    out: Optional[PathLike] = None,
    backend: Optional[str] = None,
    precision: Optional[str] = None,
    force: bool = False,
) -> Report:
    """The stability report of ``scene`` (``reeb report stability``): each
    cell of its two axes classed (on the cycle, off it, non-finite) with its
    error, in ``out`` (default ``runs/<name>-stability``)."""
    return _report("stability", scene, out, backend, precision, force)
