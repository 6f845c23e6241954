"""A scene given as a path, a TOML string or a dict, as TOML text."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping, Tuple, Union

from . import _reeb

Scene = Union[str, "os.PathLike[str]", Mapping[str, Any]]


def _plain(x: Any) -> Any:
    """JSON for numpy arrays and scalars (``json.dumps``'s ``default``)."""
    if hasattr(x, "tolist"):
        return x.tolist()
    raise TypeError(f"a scene value of type {type(x).__name__} (numbers, strings, lists, dicts)")


def scene_toml(scene: Mapping[str, Any]) -> str:
    """The TOML text of a scene given as a dict (with exactly the TOML's
    structure; numpy arrays are accepted wherever a list is)."""
    try:
        text = json.dumps(scene, default=_plain, allow_nan=True)
    except TypeError as e:
        from .errors import SceneError

        raise SceneError(str(e)) from None
    return _reeb.toml_of_json(text)


def resolve(scene: Scene) -> Tuple[str, str]:
    """``(text, path)`` of a scene: a file's text and its path, a TOML
    string (``"<string>"``), or a dict's TOML (``"<dict>"``)."""
    if isinstance(scene, Mapping):
        return scene_toml(scene), "<dict>"
    if isinstance(scene, os.PathLike) or (isinstance(scene, str) and "\n" not in scene and "=" not in scene):
        path = Path(scene)
        try:
            return path.read_text(), str(path)
        except OSError as e:
            from .errors import SceneError

            raise SceneError(f"cannot read the scene: {e.strerror or e}", path=str(path)) from None
    if isinstance(scene, str):
        return scene, "<string>"
    raise TypeError(f"a scene is a path, a TOML string or a dict, not {type(scene).__name__}")
