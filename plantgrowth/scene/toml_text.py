"""Scene data written back as TOML text (fully resolved scenes, sweep files)."""

from __future__ import annotations

import json
from typing import Any


def dict_to_toml(data: dict[str, Any]) -> str:
    """TOML text of scene-like data: top-level values first, then one ``[table]`` per dict."""
    lines = [f"{k} = {toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for key, value in data.items():
        if isinstance(value, dict):
            lines += ["", f"[{key}]"] + [f"{k} = {toml_value(v)}" for k, v in value.items()]
    return "\n".join(lines) + "\n"


def toml_value(v: Any) -> str:
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(v)  # an int, or a float: repr round-trips exactly and is valid TOML
