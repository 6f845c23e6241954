"""A scene given as a path, a TOML string or a dict, as TOML text.

A dict is written as the TOML file it spells, keys in the dict's order (the
order of the axes), and then read by exactly the rules of a scene file, so
its errors name the same fields (``params.epsilon``).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, List, Mapping, Tuple, Union

from .errors import SceneError

Scene = Union[str, "os.PathLike[str]", Mapping[str, Any]]


def _plain(x: Any, field: str) -> Any:
    """``x`` with numpy arrays and scalars as lists and Python numbers."""
    if hasattr(x, "tolist") and not isinstance(x, (str, bytes)):
        return x.tolist()
    if x is None:
        raise SceneError("None has no TOML form: leave the key out", field=field, path="<dict>")
    return x


def _value(x: Any, field: str) -> str:
    """One TOML value (inline tables for nested dicts)."""
    x = _plain(x, field)
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(x, str):
        return json.dumps(x, ensure_ascii=False)
    if isinstance(x, Mapping):
        inner = ", ".join(f"{_key(k)} = {_value(v, f'{field}.{k}')}" for k, v in x.items())
        return "{ " + inner + " }" if inner else "{}"
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_value(v, f"{field}[{i}]") for i, v in enumerate(x)) + "]"
    raise SceneError(
        f"a value of type {type(x).__name__} (numbers, strings, booleans, lists, dicts)",
        field=field,
        path="<dict>",
    )


def _key(k: Any) -> str:
    if not isinstance(k, str):
        raise SceneError(f"the key {k!r} is not a string", path="<dict>")
    bare = k and all(c.isalnum() or c in "_-" for c in k) and k.isascii()
    return k if bare else json.dumps(k)


def scene_toml(scene: Mapping[str, Any]) -> str:
    """The TOML text of a scene given as a dict (with exactly the TOML's
    structure; numpy arrays are accepted wherever a list is)."""
    top: List[str] = []
    tables: List[str] = []
    for k, v in scene.items():
        if isinstance(v, Mapping):
            tables.append(f"[{_key(k)}]")
            tables += [f"{_key(kk)} = {_value(vv, f'{k}.{kk}')}" for kk, vv in v.items()]
        else:
            top.append(f"{_key(k)} = {_value(v, k)}")
    return "\n".join(top + tables) + "\n"


def resolve(scene: Scene) -> Tuple[str, str]:
    """``(text, path)`` of a scene: a file's text and its path, a TOML
    string (``"<string>"``), or a dict's TOML (``"<dict>"``)."""
    if isinstance(scene, Mapping):
        return scene_toml(scene), "<dict>"
    looks_like_path = isinstance(scene, str) and "\n" not in scene and "=" not in scene
    if isinstance(scene, os.PathLike) or looks_like_path:
        path = Path(scene)
        try:
            return path.read_text(), str(path)
        except OSError as e:
            raise SceneError(f"cannot read the scene: {e.strerror or e}", path=str(path)) from None
    if isinstance(scene, str):
        return scene, "<string>"
    raise TypeError(f"a scene is a path, a TOML string or a dict, not {type(scene).__name__}")
