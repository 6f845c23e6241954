"""The exceptions reeb raises."""

from __future__ import annotations

from typing import Optional


class ReebError(RuntimeError):
    """A run, check or report that reeb refused or could not finish (the
    message says why, naming the path or option at fault)."""


class SceneError(ReebError):
    """A scene that is not valid: where (``line`` of ``path``, ``field``) and
    what is wrong (``message``).

    For a scene given as a dict, ``line`` counts lines of the TOML text reeb
    wrote from it (``reeb.scene_toml(d)`` shows it); ``field`` is the dotted
    key, as in the dict (``"params.epsilon"``).
    """

    def __init__(
        self,
        message: str,
        field: Optional[str] = None,
        line: Optional[int] = None,
        path: Optional[str] = None,
    ) -> None:
        self.message = message
        self.field = field
        self.line = line
        self.path = path
        where = path or "scene"
        if line is not None:
            where += f":{line}"
        text = f"{where}: {field}: {message}" if field else f"{where}: {message}"
        super().__init__(text)


class InternalError(ReebError):
    """A bug in reeb (a Rust panic, caught): please report it with the
    scene that caused it."""
