"""Write a recording as the CSV scenario set that :mod:`phid_ros.io.csvset.csv_import` reads.

One CSV per scenario (columns ``t`` and the channels, ``t`` from 0 at the scenario's
first sample) and a ``manifest.json`` naming each file with its kind, role and generator
damping, as the contract (docs/contracts.md) says. For tests and benchmarks of the CSV path,
and for users who want our simulations in a spreadsheet or another tool.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.io.csvset.csv_import import CSV_COLUMNS
from phid_ros.io.files.outputs import atomic_output, write_text
from phid_ros.io.recording import FIELD_BASES_KEY, MEASUREMENT_WINDOW_KEY, Recording
from phid_ros.io.topics import ALL_STREAMS_BY_NAME, STREAMS
from phid_ros.model.channels import CHANNELS
from phid_ros.model.conventions import NS

MANIFEST = "manifest.json"


def write_csv_set(folder: str | Path, rec: Recording) -> Path:
    """Every scenario of ``rec`` as ``folder/<name>.csv`` plus ``folder/manifest.json``; returns the manifest.

    Each file is written whole or not at all, the manifest last, so an interrupted export
    leaves no set that looks complete.
    """
    out = Path(folder)
    if not rec.scenarios:
        raise PhidError(f"{out}: the recording has no scenarios to write as a CSV set")
    names = [f"{sc.name}.csv" for sc in rec.scenarios] + [MANIFEST]
    # the set goes into a folder that may hold the recorder's own files (STEM.csv beside STEM's
    # export): a file already there is never replaced, whoever wrote it
    taken = [n for n in names if (out / n).exists() or (out / n).is_symlink()]
    if taken:
        raise PhidError(
            f"{out / taken[0]}: already exists; a CSV set is never written over a file "
            f"({len(taken)} of its {len(names)} files are taken): choose another folder"
        )
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise PhidError(f"{out}: two scenarios would be written to {twice[0]}; rename the recordings")
    t_ns, values, header = _common_samples(rec)
    out.mkdir(parents=True, exist_ok=True)
    entries = []
    for sc in rec.scenarios:
        a, b = np.searchsorted(t_ns, [sc.start_ns, sc.end_ns], side="left")
        b = min(len(t_ns), b + 1)  # end_ns is the last sample's stamp
        t = (t_ns[a:b] - t_ns[a]) / NS
        rows = np.column_stack([t, values[a:b]])
        name = f"{sc.name}.csv"
        with atomic_output(out / name) as tmp:
            np.savetxt(tmp, rows, delimiter=",", header=",".join(header), comments="", fmt="%.9g")
        entry = {"file": name, "kind": sc.kind, "role": sc.role, "generator_damping": sc.generator_damping}
        if sc.regulator:
            entry["regulator"] = sc.regulator
        if sc.reference_step is not None:
            entry["reference_step"] = sc.reference_step
        if sc.event_ns:  # the marker's event time, so a small labelled step is not searched for
            entry["event_time_s"] = (sc.event_ns - int(t_ns[a])) / NS
        entries.append(entry)
    manifest = {"f_nominal_hz": rec.f_nominal_hz, "scenarios": entries}
    if "base_mva" in rec.metadata:
        manifest["base_mva"] = float(rec.metadata["base_mva"])
    if MEASUREMENT_WINDOW_KEY in rec.metadata:
        manifest[MEASUREMENT_WINDOW_KEY] = float(rec.metadata[MEASUREMENT_WINDOW_KEY])
    if FIELD_BASES_KEY in rec.metadata:
        manifest[FIELD_BASES_KEY] = rec.metadata[FIELD_BASES_KEY]
    return write_text(out / MANIFEST, json.dumps(manifest, indent=2) + "\n")


def _common_samples(rec: Recording) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The stamps every stream shares, the channels on them (n, columns) and the columns' header:
    the CHANNELS, then a recorder's own channels where the recording kept them."""
    first = rec.streams[STREAMS[0].name]
    kept = [c for s in rec.recorder_streams().values() for c in s.channels]
    names = (*CHANNELS, *kept)
    values = np.empty((len(first.t_ns), len(names)))
    for spec in (*STREAMS, *(ALL_STREAMS_BY_NAME[n] for n in rec.recorder_streams())):
        s = rec.streams[spec.name]
        if not np.array_equal(s.t_ns, first.t_ns):
            raise PhidError(
                f"stream {spec.name}: its stamps differ from {STREAMS[0].name}'s; a CSV row needs one clock"
            )
        for c in spec.channels:
            values[:, names.index(c)] = s.channels[c]
    return first.t_ns, values, (CSV_COLUMNS[0], *names)
