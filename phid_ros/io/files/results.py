"""JSON files: results written by the tools and truth files written by the simulator."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from phid_ros.errors import ResultsError


def json_ready(obj: Any) -> Any:
    """JSON has no NaN/Inf: write them as null so every reader can parse the file."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalars
        return json_ready(obj.item())
    return obj


def write_json(path: str | Path, data: Mapping[str, Any]) -> Path:
    from phid_ros.io.files.outputs import write_text

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_text(p, json.dumps(json_ready(data), indent=2, sort_keys=False) + "\n")


def read_json(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise ResultsError(f"{p}: no such file")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ResultsError(f"{p}: not valid JSON (line {exc.lineno}: {exc.msg})") from exc
    except RecursionError:  # a few KB of [[[[...]]]]: no result nests so deep
        raise ResultsError(f"{p}: nested too deeply to be a phid result or manifest") from None
    if not isinstance(data, dict):
        raise ResultsError(f"{p}: expected a JSON object at the top level")
    return data


def truth_path_for(bag_path: str | Path) -> Path:
    """Where the simulator puts the truth file of a recording: ``<bag>.truth.json`` beside a bag
    or an .mcap, ``DIR/truth.json`` in a CSV set's folder (the set is the folder)."""
    p = Path(bag_path)
    if p.name == "manifest.json":
        return p.with_name("truth.json")
    return p.with_name(p.name + ".truth.json")
