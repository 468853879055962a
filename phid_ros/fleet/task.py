"""One fleet task: a recording in, a history row out. Runs on a Dask worker.

A task never raises for a bad recording: the one-line reason becomes a failed row, so one
corrupt file cannot stop the fleet. A worker that dies under a task is the scheduler's
business (it reruns the task elsewhere, then gives up with ``KilledWorker``, which the
driver records as a failure).
"""

from __future__ import annotations

import math
import os
import socket
import time
from typing import TYPE_CHECKING

from phid_ros import __version__
from phid_ros.errors import PhidError
from phid_ros.fleet.history import Row
from phid_ros.model.parameters import PARAMETER_NAMES
from phid_ros.provenance import method_version

if TYPE_CHECKING:  # the pipeline (and scipy.optimize) loads when a task runs, not when this is imported
    from phid_ros.api import UnitCut
    from phid_ros.ident.pipeline import IdentificationResult


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or "no message"
    return text if isinstance(exc, PhidError) else f"{type(exc).__name__}: {text}"


def process_recording(
    unit: str, path: str, content_hash: str, diagnose: bool = False, record: str | None = None
) -> Row:
    """Identify (and with ``diagnose`` also diagnose) one recording of one unit; with the unit's
    ``record`` on file (a ``.dyr``), play each of its events into the record as ``phid validate``
    does and keep the verdicts."""
    t0 = time.perf_counter()
    row = Row(unit, path, content_hash, "failed", __version__, worker=f"{socket.gethostname()}:{os.getpid()}")
    row.method_version = method_version()
    row.record = record or ""
    try:
        _identify_into(row, path, diagnose)
        row.status = "ok"
    except Exception as exc:  # noqa: BLE001 - recorded, never lost: the fleet goes on with the others
        row.error = one_line(exc)
    row.wall_s = time.perf_counter() - t0
    return row


def _identify_into(row: Row, path: str, diagnose: bool) -> None:
    from phid_ros.api import cut_unit, identify_unit
    from phid_ros.ident.pipeline import IdentifyOptions

    unit = cut_unit([path])  # part by part, as phid identify: a long recording's windows, not its hours
    row.start_ns, row.end_ns = unit.cuts[0].span_ns
    options = IdentifyOptions(baseline=False, validate=not diagnose)
    found = identify_unit(unit, options)  # the machine, its exciter and governor, as phid identify
    scenarios, res = found.scenarios, found.result
    row.controls = found.document["controls"]
    row.method = f"three-stage ({res.method})"
    row.flags = [f"read: {w}" for w in unit.recording.warnings]
    for name in PARAMETER_NAMES:
        est = res.estimates.get(name)
        if est is None:
            continue
        row.values[name], row.stds[name], row.identifiable[name] = est.value, est.std, est.identifiable
        if est.note:
            row.flags.append(f"{name}: {est.note}")
    row.flags += [p for p in res.problems if p not in res.label_disputes]
    if diagnose:
        _diagnose_into(row, scenarios, res, unit.recording.f_nominal_hz)
    if row.record:
        _check_record(row, unit)


def _check_record(row: Row, unit: UnitCut) -> None:
    """Each event played into the record on file, one verdict each (ScenarioCheck.as_json, with
    the event's stamp); a record that cannot be read or played is said, the identification kept."""
    from phid_ros.api import RecordOnFile, validate_cut

    stamps = {sc.name: int(sc.frame.t_ns[sc.k_event]) for cut in unit.cuts for sc in cut.scenarios}
    try:
        found = validate_cut(RecordOnFile(row.record), unit)
    except PhidError as exc:
        row.flags.append(f"record on file not checked: {one_line(exc)}")
        return
    for sc in found.result.scenarios:
        if not sc.checks:
            continue
        verdict = sc.as_json()
        verdict["event_ns"] = stamps.get(sc.scenario)
        verdict["loop_closed"] = sc.loop_closed
        row.verdicts.append(verdict)


def _diagnose_into(row: Row, scenarios: list, res: IdentificationResult, f_hz: float) -> None:
    from phid_ros.diagnose.options import DiagnoseOptions
    from phid_ros.diagnose.results import to_json
    from phid_ros.diagnose.workflow import diagnose

    # workers=0: the candidates of a round go to the fleet's own cluster (phid_ros.cluster.Jobs)
    d = diagnose(scenarios, res.parameters, DiagnoseOptions.after(res, f_nominal_hz=f_hz, workers=0))
    doc = to_json(d, None, None)
    row.effects = [{"name": e["name"], "parameters": e["parameters"]} for e in doc["effects"]]
    row.method += " + diagnosis"
    if row.effects:
        # The three-stage set is biased by the named physics (saturation moved T'_d0 by +944 % on
        # the shipped bag): keep the refit with the effects instead, and say it has no std yet,
        # so it never counts as a well-identified set for drift.
        for name, value in doc["parameters"].items():
            if name in row.values:
                row.values[name], row.stds[name] = float(value), math.nan
        row.flags.append(
            "effects named: values are the output-error refit with "
            + ", ".join(e["name"] for e in row.effects)
            + " (no std)"
        )
