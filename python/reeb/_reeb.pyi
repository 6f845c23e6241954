"""Type stubs of the extension module `reeb._reeb` (the Rust engine)."""

from os import PathLike
from typing import Any, Callable, List, Optional, Union

__version__: str

_Path = Union[str, PathLike[str]]

def run(
    text: str,
    path: str,
    out: _Path,
    preview: bool = False,
    progress: Optional[Callable[[int, int], None]] = None,
    **options: Any,
) -> str:
    """Runs the scene `text` (read from `path`) into `out` as `reeb run`
    does; returns summary.json's text. `options` are `reeb run`'s options
    (`run_option_names()`), each parsed as its flag: a value is the flag's
    text, True a flag given, None and False none."""

def run_option_names() -> List[str]:
    """The long names of `reeb run`'s options, `_` for `-`."""

def merge(out: _Path, force: bool = False) -> str:
    """`reeb merge`: finishes a run made in shards; returns its summary."""

def check(text: str, path: str, precision: Optional[str] = None, out: Optional[_Path] = None) -> str:
    """Every gate of `run` without running; JSON."""

def verify(backend: str = "cpu", precision: str = "f64") -> str:
    """`reeb verify`'s rows as JSON."""

def info() -> str:
    """`reeb info` as JSON."""

def report(
    kind: str,
    text: str,
    path: str,
    out: Optional[_Path] = None,
    backend: Optional[str] = None,
    precision: Optional[str] = None,
    force: bool = False,
) -> str:
    """`reeb report KIND`; returns the path of the report's main file in its directory."""

def _panic(message: str) -> None:
    """Panics on the engine's thread (tests only): raises `reeb.InternalError`."""
