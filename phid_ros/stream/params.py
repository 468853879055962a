"""The tunables of the online pipeline: one table, declared as ROS parameters by the nodes.

Each entry: name, type, default, range, description and where it lands in
:class:`~phid_ros.stream.pipeline.PipelineSettings` (or the node itself).
``validate`` gives the reason a value is refused; the nodes return it to
``ros2 param set`` and keep the old value. ``config/phid.yaml`` carries the same
defaults, and a test keeps the two equal.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from phid_ros.controls.models import KINDS_IN_ORDER as CONTROL_KINDS
from phid_ros.errors import ParameterError
from phid_ros.ident.constraints import Constraints, parse_constraints
from phid_ros.ident.pipeline import IdentifyOptions
from phid_ros.model.bounds import Bounded
from phid_ros.model.channels import CHANNELS
from phid_ros.model.conventions import seconds_to_ns
from phid_ros.stream.detector import POST_EVENT_S, PRE_EVENT_S, STEP_PLATEAU_S
from phid_ros.stream.pipeline import PipelineSettings

# the streams that may report slower than the grid (a 50 Hz PMU beside 1 kHz PT/CT); the
# PT/CT stream is the grid's own rate
RATED_STREAMS = ("encoder", "pmu", "excitation")


@dataclass(frozen=True)
class Tunable(Bounded):
    name: str
    type: type
    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    runtime: bool = True  # can change while running


SENSORS: tuple[Tunable, ...] = (  # how both nodes subscribe to the sensor topics
    Tunable(
        "reliable_qos", bool, False, "subscribe with reliable QoS instead of the sensor-data profile", runtime=False
    ),
    Tunable(
        "queue_depth",
        int,
        2000,
        "sensor messages queued per topic (2000: 200 s of 100-sample blocks at 1 kHz, 10 s at 20x playback)",
        10,
        100000,
        runtime=False,
    ),
    *(
        Tunable(
            f"{stream}_rate_hz",
            float,
            0.0,
            f"the {stream} stream's own sample rate, which /diagnostics expects (0: the grid's, sample_rate_hz)",
            0.0,
            100000.0,
            runtime=False,
        )
        for stream in RATED_STREAMS
    ),
    Tunable(
        "not_recorded",
        str,
        "",
        "comma-separated channels the plant's recorder never carries (a trend log: omega,delta,p_m): absent, "
        "not dead; windows without them are used",
        runtime=False,
    ),
)

# both nodes: a bag that finished or a feed that stopped is the end of the input, and each does
# what phid replay does at its end (the ingest node cuts the windows still open with what came, the
# recalibration node runs the owed recalibration): an event in a recording's last 30 s was lost
END_OF_DATA = Tunable(
    "end_of_data_s",
    float,
    3.0,
    "wall time without sensor data after which the input counts as ended: open windows are cut, the owed "
    "recalibration runs",
    0.5,
    3600.0,
)

# both nodes are managed (lifecycle) nodes; a lifecycle manager, or `ros2 lifecycle set`, may
# drive them instead
AUTOSTART = Tunable(
    "autostart",
    bool,
    True,
    "configure and activate at start; false: start unconfigured and wait for the lifecycle transitions",
    runtime=False,
)

# both nodes align the streams (the recalibration node for the Hamiltonian and the streams' health)
SAMPLE_RATE = Tunable(
    "sample_rate_hz",
    float,
    1000.0,
    "rate of the common time grid the streams are aligned on (a recorder's own: 208.3332031 for 4.800003 ms)",
    10.0,
    100000.0,
    runtime=False,
)

INGEST: tuple[Tunable, ...] = (
    (AUTOSTART,)
    + SENSORS
    + (
        SAMPLE_RATE,
        Tunable(
            "ring_seconds", float, 120.0, "length of the ring buffer of aligned samples", 40.0, 3600.0, runtime=False
        ),
        Tunable("pre_event_s", float, PRE_EVENT_S, "event window before the disturbance", 0.2, 10.0),
        Tunable("post_event_s", float, POST_EVENT_S, "event window after the disturbance", 2.0, 120.0),
        Tunable(
            "plateau_s",
            float,
            STEP_PLATEAU_S,
            "how far a field step's window reaches back for its pre-step plateau (halfway from the event before, "
            "or where the recording resumed; at most the ring buffer's oldest sample)",
            0.0,
            3600.0,
        ),
        Tunable(
            "process_period_s",
            float,
            0.1,
            "how often buffered samples are aligned and scanned",
            0.01,
            5.0,
            runtime=False,
        ),
        Tunable("stale_timeout_s", float, 2.0, "a stream silent this long is reported STALE", 0.1, 60.0),
        END_OF_DATA,
    )
)

RECALIBRATION: tuple[Tunable, ...] = (
    (AUTOSTART,)
    + SENSORS
    + (
        SAMPLE_RATE,
        Tunable("hamiltonian_rate_hz", float, 10.0, "rate of the Hamiltonian output", 0.1, 100.0),
        Tunable("diagnostics_period_s", float, 1.0, "period of /diagnostics", 0.1, 60.0, runtime=False),
        Tunable("min_interval_s", float, 300.0, "least stream time between automatic recalibrations", 0.0, 86400.0),
        Tunable("latest_per_kind", int, 10, "events per kind a recalibration uses (the newest)", 1, 100),
        Tunable("max_relative_jump", float, 0.5, "relative change beyond which a new set is implausible", 0.01, 10.0),
        Tunable("auto_recalibrate", bool, True, "recalibrate automatically when enough events are stored"),
        END_OF_DATA,
        Tunable(
            "store_path", str, "phid_events.sqlite", "event store file (SQLite); ':memory:' keeps none", runtime=False
        ),
        Tunable(
            "unit_id",
            str,
            "",
            "the generating unit watched; the store refuses another unit's events (empty: the node namespace)",
            runtime=False,
        ),
        Tunable(
            "record",
            str,
            "",
            "the unit's record on file (a PSS/E .dyr: machine, exciter, governor, stabiliser), played into every "
            "usable event as phid validate plays it; its verdicts on model_validation (empty: none)",
            runtime=False,
        ),
        Tunable(
            "record_warn_events",
            int,
            2,
            "the record's state is WARN when it failed a check on this many of the last record_window events",
            1,
            100,
            runtime=False,
        ),
        Tunable("record_window", int, 5, "the last events the record's state is judged on", 1, 100, runtime=False),
        Tunable(
            "held",
            str,
            "",
            "datasheet values every recalibration holds, NAME=VALUE separated by commas (a recorder without the "
            "rotor angle: X_q=0.62), as phid identify --fix",
            runtime=False,
        ),
        Tunable(
            "saturation",
            str,
            "",
            "the machine's open-circuit curve S(1.0),S(1.2) from its datasheet, as phid identify --saturation "
            "(empty: none; the field current's base then needs a no-load plateau below the knee)",
            runtime=False,
        ),
        Tunable(
            "control_systems",
            str,
            "exciter,stabiliser",
            "control systems fitted beside the machine at each recalibration, comma-separated among exciter, "
            "governor, stabiliser (empty: none), as phid identify fits them",
            runtime=False,
        ),
        Tunable("tracking_enabled", bool, False, "run the sliding-window tracker too"),
        Tunable("tracking_window_s", float, 300.0, "tracker window", 30.0, 3600.0, runtime=False),
        Tunable("tracking_hop_s", float, 60.0, "tracker hop", 1.0, 3600.0, runtime=False),
    )
)


def validate(table: tuple[Tunable, ...], name: str, value: Any, *, running: bool = True) -> str | None:
    """Why ``value`` is refused for ``name``, or None when it is acceptable."""
    spec = next((t for t in table if t.name == name), None)
    if spec is None:
        return f"unknown parameter {name!r}"
    if running and not spec.runtime:
        return f"{name} cannot change while the node is configured; deactivate and clean it up, set it, configure again"
    if spec.type is bool:
        ok = isinstance(value, bool)
    elif spec.type is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif spec.type is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    else:
        ok = isinstance(value, spec.type)
    if not ok:
        return f"{name} must be a {spec.type.__name__}, got {value!r}"
    if name == "not_recorded":
        unknown = [c for c in channel_list(value) if c not in CHANNELS]
        if unknown:
            return f"not_recorded: unknown channel(s) {', '.join(unknown)}; channels: {', '.join(CHANNELS)}"
    if name == "control_systems":
        unknown = [k for k in channel_list(value) if k not in CONTROL_KINDS]
        if unknown:
            return f"control_systems: unknown {', '.join(unknown)}; among {', '.join(CONTROL_KINDS)}"
    if name in ("held", "saturation"):
        try:
            held_constraints(value if name == "held" else "", value if name == "saturation" else "")
        except ParameterError as exc:
            return f"{name}: {exc}"
    return spec.outside(value, str)


def held_constraints(held: str, saturation: str) -> Constraints:
    """The ``held`` and ``saturation`` parameters (phid identify's --fix and --saturation) as the
    recalibration's constraints."""
    return parse_constraints([h.strip() for h in held.split(",") if h.strip()], saturation=saturation.strip() or None)


def channel_list(text: str) -> frozenset[str]:
    """A comma-separated channel list (the ``not_recorded`` parameter) as a set."""
    return frozenset(c.strip() for c in text.split(",") if c.strip())


def pipeline_settings(
    values: dict[str, Any], *, detect: bool, store_path: str = ":memory:", unit: str = ""
) -> PipelineSettings:
    """PipelineSettings from parameter values (missing ones take their defaults)."""
    from phid_ros.stream.detector import DetectorSettings
    from phid_ros.stream.recalibration import RecalibrationPolicy
    from phid_ros.stream.tracker import TrackerSettings

    v = {t.name: t.default for t in INGEST + RECALIBRATION}
    v.update(values)
    return PipelineSettings(
        period_ns=seconds_to_ns(1.0 / v["sample_rate_hz"]),
        ring_seconds=float(v["ring_seconds"]),
        detector=DetectorSettings(
            pre_s=float(v["pre_event_s"]), post_s=float(v["post_event_s"]), plateau_s=float(v["plateau_s"])
        ),
        hamiltonian_rate_hz=float(v["hamiltonian_rate_hz"]),
        stale_timeout_s=float(v["stale_timeout_s"]),
        store_path=store_path,
        unit=unit,
        auto_recalibrate=bool(v["auto_recalibrate"]),
        policy=RecalibrationPolicy(
            latest_per_kind=int(v["latest_per_kind"]),
            min_interval_s=float(v["min_interval_s"]),
            max_relative_jump=float(v["max_relative_jump"]),
        ),
        detect=detect,
        tracking_enabled=bool(v["tracking_enabled"]),
        tracking=TrackerSettings(window_s=float(v["tracking_window_s"]), hop_s=float(v["tracking_hop_s"])),
        expected_rates_hz={s: float(v[f"{s}_rate_hz"]) for s in RATED_STREAMS if v[f"{s}_rate_hz"] > 0},
        not_recorded=channel_list(str(v["not_recorded"])),
        control_systems=tuple(k for k in CONTROL_KINDS if k in channel_list(str(v["control_systems"]))),
        identify=IdentifyOptions(baseline=False, constraints=held_constraints(str(v["held"]), str(v["saturation"]))),
    )


def apply(settings: PipelineSettings, name: str, value: Any) -> PipelineSettings:
    """A run-time change applied to live settings (already validated)."""
    if name in ("pre_event_s", "post_event_s", "plateau_s"):
        d = settings.detector
        d = replace(d, pre_s=float(value)) if name == "pre_event_s" else d
        d = replace(d, post_s=float(value)) if name == "post_event_s" else d
        d = replace(d, plateau_s=float(value)) if name == "plateau_s" else d
        return replace(settings, detector=d)
    if name in ("min_interval_s", "latest_per_kind", "max_relative_jump"):
        return replace(settings, policy=replace(settings.policy, **{name: value}))
    if name in ("hamiltonian_rate_hz", "auto_recalibrate", "stale_timeout_s", "tracking_enabled"):
        return replace(settings, **{name: value})
    return settings
