"""Build the output messages from the pipeline's results, for any message-class table.

``types`` maps a full type name (``phid_msgs/msg/GeneratorParameters``) to a class
that takes its fields as keyword arguments: the rosbags typestore classes (for
``phid replay`` writing a bag) and the rclpy generated classes (for the nodes)
both do. ``seq`` turns a float array into whatever the class wants for a
``float64[]`` field (numpy for rosbags; ``array.array('d')`` for rclpy, which
then skips its per-element checks).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from phid_ros.io.topics import RECORDER_CHANNELS
from phid_ros.model.channels import CHANNELS, channel_columns
from phid_ros.model.conventions import NS, seconds_to_ns, split_stamp, stamp_ns
from phid_ros.model.parameters import PARAMETER_NAMES
from phid_ros.stream.align import StreamHealth
from phid_ros.stream.detector import Event, EventWindow
from phid_ros.stream.energy import EnergySamples
from phid_ros.stream.levels import Level
from phid_ros.stream.recalibration import RecalibrationOutcome
from phid_ros.stream.record_check import EventVerdict, RecordCheck
from phid_ros.stream.tracker import TRACKED, TrackPoint

Types = Mapping[str, Callable[..., Any]]
Seq = Callable[[Any], Any]


def numpy_seq(a: Any) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def numpy_bools(a: Any) -> np.ndarray:
    """``bool[]`` for rosbags; rclpy takes a plain list (pass ``list``)."""
    return np.asarray(a, dtype=bool)


def stamp(types: Types, ns: int) -> Any:
    sec, nanosec = split_stamp(ns)
    return types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def header(types: Types, ns: int, frame_id: str = "generator") -> Any:
    return types["std_msgs/msg/Header"](stamp=stamp(types, ns), frame_id=frame_id)


def event_message(types: Types, e: Event) -> Any:
    return types["phid_msgs/msg/DisturbanceEvent"](
        header=header(types, e.inception_ns),
        event_id=e.event_id,
        kind=e.kind,
        inception=stamp(types, e.inception_ns),
        clearing=stamp(types, e.clearing_ns),
        severity=float(e.severity),
        v_prefault=float(e.v_prefault),
    )


def window_message(types: Types, w: EventWindow, seq: Seq = numpy_seq) -> Any:
    e = w.event
    arrays = {c: seq(v) for c, v in channel_columns(w.values).items()}
    arrays |= {c: seq(w.recorded[c] if c in w.recorded else np.zeros(0)) for c in RECORDER_CHANNELS}
    return types["phid_msgs/msg/EventWindow"](
        header=header(types, int(w.t_ns[0]) if len(w.t_ns) else e.inception_ns),
        event_id=e.event_id,
        kind=e.kind,
        inception=stamp(types, e.inception_ns),
        clearing=stamp(types, e.clearing_ns),
        sample_period=w.period_ns / NS,
        **arrays,
    )


def parameters_message(
    types: Types, outcome: RecalibrationOutcome, seq: Seq = numpy_seq, bools: Seq = numpy_bools
) -> Any | None:
    """The set in force after a recalibration (the new one, or the last good one kept); before
    any set is in force, the parameters a partial run determined, alone (``names`` lists them:
    the others are withheld, and ``status`` names them and why)."""
    p = outcome.parameters
    if p is None:
        return partial_message(types, outcome, seq, bools) if outcome.determined else None
    values = p.as_dict()
    res = outcome.result if outcome.accepted else None
    est = res.estimates if res else {}
    std = [est[n].std if n in est else math.nan for n in PARAMETER_NAMES]
    ident = [bool(est[n].identifiable) if n in est else False for n in PARAMETER_NAMES]
    objective = res.stage3.objective if res and res.stage3 else math.nan
    fit = res.validation.worst("rmse") if res and res.validation else math.nan
    return types["phid_msgs/msg/GeneratorParameters"](
        header=header(types, outcome.stream_time_ns),
        names=list(PARAMETER_NAMES),
        values=seq([values[n] for n in PARAMETER_NAMES]),
        std_dev=seq(std),
        identifiable=bools(ident),
        method=res.method if res else "",
        event_ids=list(outcome.event_ids),
        objective=float(objective),
        fit_rmse=float(fit),
        status=outcome.status,
    )


def controls_messages(
    types: Types, outcome: RecalibrationOutcome, seq: Seq = numpy_seq, bools: Seq = numpy_bools
) -> list[Any]:
    """One ControlParameters message per kind the run fitted (or said why not): the exciter, and
    the stabiliser and governor where recorded, published beside the machine's parameters."""
    from phid_ros.controls.fit import ControlFit

    out = []
    for kind, fit in outcome.controls.items():
        if isinstance(fit, ControlFit):
            names = list(fit.parameters)

            def number(v: float | None) -> float:
                return math.nan if v is None else float(v)

            fields: dict[str, Any] = {
                "model": fit.model if fit.named else "",
                "fitted_model": fit.model,
                "names": names,
                "values": seq([number(fit.parameters[n]) for n in names]),
                "std_dev": seq([number(fit.uncertainty.get(n)) for n in names]),
                "identifiable": bools([bool(fit.identifiable.get(n)) for n in names]),
                "limits_reached": sorted(fit.limits),
                "fit_rmse": float(fit.fit_rmse),
                "why": fit.why,
            }
        else:
            fields = {"model": "", "fitted_model": "", "names": [], "values": seq([]), "std_dev": seq([])}
            fields |= {"identifiable": bools([]), "limits_reached": [], "fit_rmse": math.nan, "why": fit}
        msg = types["phid_msgs/msg/ControlParameters"](
            header=header(types, outcome.stream_time_ns), kind=kind, event_ids=list(outcome.event_ids), **fields
        )
        out.append(msg)
    return out


def partial_message(types: Types, outcome: RecalibrationOutcome, seq: Seq = numpy_seq, bools: Seq = numpy_bools) -> Any:
    """The parameters an incomplete recalibration determined, and only those (see :func:`parameters_message`)."""
    est = outcome.determined
    names = [n for n in PARAMETER_NAMES if n in est]
    res = outcome.result
    return types["phid_msgs/msg/GeneratorParameters"](
        header=header(types, outcome.stream_time_ns),
        names=names,
        values=seq([est[n].value for n in names]),
        std_dev=seq([est[n].std for n in names]),
        identifiable=bools([True for _ in names]),
        method=res.method if res else "",
        event_ids=list(outcome.event_ids),
        objective=float(res.stage3.objective) if res and res.stage3 else math.nan,
        fit_rmse=math.nan,  # no complete model to validate
        status=outcome.status,
    )


def tracked_message(types: Types, point: TrackPoint, seq: Seq = numpy_seq, bools: Seq = numpy_bools) -> Any:
    """One tracker hop: the tracked parameters estimated over the window ending at its stamp."""
    names = [n for n in TRACKED if n in point.estimates]
    return types["phid_msgs/msg/GeneratorParameters"](
        header=header(types, point.t_ns),
        names=names,
        values=seq([point.estimates[n].value for n in names]),
        std_dev=seq([point.estimates[n].std for n in names]),
        identifiable=bools([bool(point.estimates[n].identifiable) for n in names]),
        method="tracker",
        event_ids=[],
        objective=math.nan,
        fit_rmse=math.nan,
        status="; ".join(point.alarms) or "ok",
    )


def hamiltonian_messages(types: Types, e: EnergySamples) -> list[Any]:
    cls = types["phid_msgs/msg/HamiltonianState"]
    return [
        cls(
            header=header(types, int(e.t_ns[k])),
            value=float(e.value[k]),
            kinetic=float(e.kinetic[k]),
            magnetic_d=float(e.magnetic_d[k]),
            magnetic_q=float(e.magnetic_q[k]),
            dissipation=float(e.dissipation[k]),
            supply=float(e.supply[k]),
            passivity_margin=float(e.passivity_margin[k]),
            delta=float(e.delta[k]),
            omega=float(e.omega[k]),
            e_q_prime=float(e.e_q_prime[k]),
            e_d_prime=float(e.e_d_prime[k]),
        )
        for k in range(len(e))
    ]


def verdict_message(types: Types, v: EventVerdict, seq: Seq = numpy_seq, bools: Seq = numpy_bools) -> Any:
    """The record's verdict on one event (phid_msgs/ModelValidation), each check as
    ``phid validate``'s JSON holds it."""
    return types["phid_msgs/msg/ModelValidation"](
        header=header(types, v.stream_time_ns),
        event_id=v.event_id,
        kind=v.kind,
        record=v.record,
        passed=bool(v.passed),
        channels=[c.channel for c in v.checks],
        standards=[c.standard for c in v.checks],
        max_errors=seq([c.max_error for c in v.checks]),
        bands=seq([c.band for c in v.checks]),
        check_passed=bools([bool(c.passed) for c in v.checks]),
        simulated_by=[c.simulated_by for c in v.checks],
        notes=list(v.notes),
        level=str(v.level),
        status=v.status,
        drifting=list(v.drifting),
    )


def diagnostics_message(
    types: Types,
    now_ns: int,
    health: Mapping[str, StreamHealth],
    recalibration: RecalibrationOutcome | None,
    node: str = "phid",
    *,
    stream_now_ns: int | None = None,
    stale_ns: int = 2 * NS,
    level: Callable[[int], Any] = int,
    unit: str = "",
    record: RecordCheck | None = None,
) -> Any:
    """diagnostic_msgs/DiagnosticArray: one status per stream, one for recalibration.

    ``unit`` (the pipeline's, or the node's namespace) is each status's ``hardware_id`` and the
    prefix of its name (``phid/unit3: pt_ct stream``), so that a plant's /diagnostics, shared by
    every unit's monitor, is grouped per unit (Foxglove's summary by hardware id, an aggregator by
    name); without one, ``generator`` and ``phid: ...`` as before.

    ``now_ns`` is the receiver's clock; ``stream_now_ns`` the newest stamp of any stream, so a
    stream that stopped while the others go on is STALE on a replayed recording too. ``level``
    makes the message's ``byte`` field: an int for the rosbags typestore, ``bytes([v])`` for rclpy.
    ``record``: the unit's record on file (the monitor's ``record``), its state one status more.
    """
    kv = types["diagnostic_msgs/msg/KeyValue"]
    status_cls = types["diagnostic_msgs/msg/DiagnosticStatus"]
    unit_name = unit.strip("/")
    hardware_id = unit_name or "generator"
    prefix = f"{node}/{unit_name}" if unit_name else node

    def status(number: Level, what: str, message: str, values: list[Any]) -> Any:
        return status_cls(
            level=level(int(number)), name=f"{prefix}: {what}", message=message, hardware_id=hardware_id, values=values
        )

    statuses = []
    for name, h in health.items():
        name_level, message = h.status(now_ns, stream_now_ns=stream_now_ns, stale_ns=stale_ns)
        values = [
            kv(key=k, value=str(v))
            for k, v in (
                ("rate_hz", f"{h.rate_hz():.1f}"),
                ("stamp_lag_s", f"{h.lag_ns / NS:.3f}"),
                ("samples", h.samples),
                ("accepted", h.accepted),
                ("dropped", h.dropped),
                ("duplicates", h.duplicates),
                ("out_of_order", h.out_of_order),
                ("nonfinite", h.nonfinite),
                ("implausible", h.implausible),
                ("missing", h.missing),
                ("zero_stamps", h.zero_stamps),
                ("wild_stamps", h.wild_stamps),
                ("malformed", h.malformed),
                ("gaps", h.gaps),
                ("pauses", h.pauses),  # of the gaps, those between marked tests: nothing lost
                ("clock_jumps", h.clock_jumps),
            )
        ]
        statuses.append(status(name_level, f"{name} stream", message, values))

    if recalibration is not None:
        statuses.append(status(recalibration.level, "recalibration", recalibration.status, []))
    if record is not None:  # the unit's record on file: OK while it passes, WARN, ERROR (record_check.py)
        record_level, message = record.status()
        values = [kv(key=k, value=v) for k, v in record.diagnostic_values()]
        statuses.append(status(record_level, "record on file", message, values))
    return types["diagnostic_msgs/msg/DiagnosticArray"](header=header(types, now_ns), status=statuses)


# -- incoming messages -> pipeline data ------------------------------------------------------
def block_arrays(msg: Any, channels: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The channel arrays of a sensor block message, without copying where the buffer allows."""
    return {c: np.asarray(getattr(msg, c), dtype=np.float64) for c in channels}


def window_from_message(msg: Any) -> EventWindow:
    """An EventWindow message (from the ingest node) back into a window; stale ones are marked."""
    period = seconds_to_ns(msg.sample_period)
    values = np.column_stack([np.asarray(getattr(msg, c), dtype=np.float64) for c in CHANNELS])
    t = stamp_ns(msg.header.stamp) + np.arange(len(values), dtype=np.int64) * period
    ev = Event(
        event_id=msg.event_id,
        kind=msg.kind,
        inception_ns=stamp_ns(msg.inception),
        clearing_ns=stamp_ns(msg.clearing),
        severity=math.nan,
        v_prefault=math.nan,
        segment=0,
    )
    recorded = {c: x for c in RECORDER_CHANNELS if len(x := np.asarray(getattr(msg, c), dtype=np.float64)) == len(t)}
    w = EventWindow(t_ns=t, values=values, period_ns=period, event=ev, recorded=recorded if len(t) else {})
    if period <= 0 or len(values) == 0:
        w.usable, w.reason = False, "empty window or bad sample period"
    # its samples are judged where the deployment's channels are known (MonitorPipeline.add_window)
    return w
