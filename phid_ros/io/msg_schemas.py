"""Load the ROS 2 interface definitions in ``msg_schemas/`` into a rosbags typestore.

``msg_schemas/`` is the single source of truth for the messages: colcon builds it
as the ``phid_msgs`` interface package on a ROS machine, and this module parses
the same ``.msg`` files at run time so bags are written and read without ROS.
"""

from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from phid_ros.errors import SchemaError

INTERFACE_PACKAGE = "phid_msgs"
ENV_VAR = "PHID_MSG_SCHEMAS"

# The only standard types our messages use, as ROS 2 Jazzy defines them. Registering
# just these (not the ~200 types of the full Jazzy store) keeps a cold start short;
# a test checks that their definitions and type hashes equal the full store's.
BASE_TYPES: dict[str, str] = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    # /diagnostics, as diagnostic_updater publishes it
    "diagnostic_msgs/msg/KeyValue": "string key\nstring value",
    "diagnostic_msgs/msg/DiagnosticStatus": (
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\n"
        "byte level\nstring name\nstring message\nstring hardware_id\ndiagnostic_msgs/KeyValue[] values"
    ),
    "diagnostic_msgs/msg/DiagnosticArray": "std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status",
}


def _candidates() -> list[Path]:
    here = Path(__file__).resolve()
    out: list[Path] = []
    if os.environ.get(ENV_VAR):
        out.append(Path(os.environ[ENV_VAR]))
    out.append(here.parents[2] / "msg_schemas")  # source tree / editable install
    out.append(here.parents[1] / "msg_schemas_data")  # installed wheel (see setup.py)
    out.append(Path(sys.prefix) / "share" / "phid_ros" / "msg_schemas")  # data_files
    # colcon install: <ws>/install/phid_ros/lib/pythonX.Y/site-packages/phid_ros/io/ -> share/
    for parent in here.parents:
        if parent.name == "lib":
            out.append(parent.parent / "share" / "phid_ros" / "msg_schemas")
            break
    return out


def schema_dir() -> Path:
    """The folder holding ``msg/*.msg``; the first candidate that has them."""
    for cand in _candidates():
        if (cand / "msg").is_dir() and any((cand / "msg").glob("*.msg")):
            return cand
    tried = ", ".join(str(c) for c in _candidates())
    raise SchemaError(f"message schemas not found (set {ENV_VAR}); looked in: {tried}")


def msg_files(root: Path | None = None) -> dict[str, Path]:
    """Full type name (``phid_msgs/msg/Name``) -> .msg path."""
    root = root or schema_dir()
    return {f"{INTERFACE_PACKAGE}/msg/{p.stem}": p for p in sorted((root / "msg").glob("*.msg"))}


@lru_cache(maxsize=4)
def typestore(root: str | None = None) -> Typestore:
    """A typestore with the phid_msgs types and the Jazzy types they use (cached)."""
    store = get_typestore(Stores.EMPTY)
    for name, text in BASE_TYPES.items():
        store.register(get_types_from_msg(text, name))
    types: dict = {}
    for name, path in msg_files(Path(root) if root else None).items():
        try:
            types.update(get_types_from_msg(path.read_text(encoding="utf-8"), name))
        except Exception as exc:  # the parser raises several types; all mean a bad .msg
            raise SchemaError(f"{path}: cannot parse message definition: {exc}") from exc
    store.register(types)
    return store
