"""The files phid writes and keeps: outputs written whole or not at all, results JSON, content digests,
SQLite schema versions, YAML documents.

The names other parts of phid use, importable from here; each module has the rest."""

from __future__ import annotations

from phid_ros.io.files.digest import content_hash, distinct_recordings, recording_files, stat_key
from phid_ros.io.files.outputs import (
    CANNOT_WRITE,
    OutputError,
    atomic_output,
    final_name,
    partial_path,
    refuse_inputs,
    write_text,
)
from phid_ros.io.files.results import read_json, truth_path_for, write_json
from phid_ros.io.files.sqlite_schema import check_intact, migrate, table_columns, user_version
from phid_ros.io.files.yaml_doc import MAX_YAML_BYTES, YamlDocError, load_yaml, load_yaml_text

__all__ = [
    "CANNOT_WRITE",
    "MAX_YAML_BYTES",
    "OutputError",
    "YamlDocError",
    "atomic_output",
    "check_intact",
    "content_hash",
    "distinct_recordings",
    "final_name",
    "load_yaml",
    "load_yaml_text",
    "migrate",
    "partial_path",
    "read_json",
    "recording_files",
    "refuse_inputs",
    "stat_key",
    "table_columns",
    "truth_path_for",
    "user_version",
    "write_json",
    "write_text",
]
