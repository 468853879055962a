"""The online monitor: sensor blocks in; events, windows, parameters, energy and health out.

One object, :class:`MonitorPipeline`, holds the whole live chain (aligner ->
ring buffer -> detector -> event store -> recalibration worker -> energy). The
ROS nodes and ``phid replay`` call exactly these methods; neither owns logic.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from phid_ros.ident.pipeline import IdentifyOptions
from phid_ros.io.recording import ScenarioInfo
from phid_ros.io.topics import RECORDER_STREAMS
from phid_ros.model.channels import CHANNELS
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.stream.align import Aligner, Run, StreamHealth
from phid_ros.stream.detector import Detector, DetectorSettings, Event, EventWindow, stale_data
from phid_ros.stream.energy import EnergySamples, energy
from phid_ros.stream.levels import Level
from phid_ros.stream.recalibration import RecalibrationOutcome, RecalibrationPolicy, Recalibrator
from phid_ros.stream.record_check import EventVerdict, RecordCheck
from phid_ros.stream.recorder import RecorderBuffer
from phid_ros.stream.ring import RingBuffer
from phid_ros.stream.store import EventStore
from phid_ros.stream.tracker import SlidingTracker, TrackerSettings, TrackPoint


@dataclass
class PipelineSettings:
    period_ns: int = 1_000_000
    ring_seconds: float = 120.0
    detector: DetectorSettings = field(default_factory=DetectorSettings)
    hamiltonian_rate_hz: float = 10.0
    stale_timeout_s: float = 2.0  # a stream without samples this long (stream time) is STALE
    store_path: str = ":memory:"
    unit: str = ""  # the generating unit this pipeline watches; a store holds one unit's events
    auto_recalibrate: bool = True
    policy: RecalibrationPolicy = field(default_factory=RecalibrationPolicy)
    identify: IdentifyOptions = field(default_factory=lambda: IdentifyOptions(baseline=False))
    # the control systems each recalibration fits beside the machine (phid identify's controls)
    control_systems: tuple[str, ...] = ("exciter", "stabiliser")
    initial_parameters: GeneratorParameters | None = None
    detect: bool = True  # False: windows arrive from elsewhere (the recalibration node gets them by topic)
    # False: windows are handed on, not kept (the ingest node: the recalibration node keeps them; an
    # in-memory store that nothing reads would grow by 2.4 MB an event for as long as the node runs)
    keep_windows: bool = True
    # sliding-window tracking of drift: it starts on tracking_base, or without one on the first set
    # identified, from the oldest data still in the ring buffer; switched off, it is dropped
    tracking_enabled: bool = False
    tracking: TrackerSettings = field(default_factory=TrackerSettings)
    tracking_base: GeneratorParameters | None = None
    # stream -> the rate /diagnostics expects of it, where it is not the grid's (a 50 Hz PMU)
    expected_rates_hz: dict[str, float] = field(default_factory=dict)
    # channels the plant's recorder never carries (a trend log: no rotor angle, speed, P_m): not
    # dead when NaN, and a window without them is usable (its scenario marks them absent)
    not_recorded: frozenset[str] = frozenset()

    def __post_init__(self) -> None:
        # one declaration for the aligner, the detector and the recalibration's policy
        if self.not_recorded != self.detector.not_recorded:
            self.detector = dataclasses.replace(self.detector, not_recorded=frozenset(self.not_recorded))
        if self.not_recorded != self.policy.not_recorded:
            self.policy = dataclasses.replace(self.policy, not_recorded=frozenset(self.not_recorded))
        d = self.detector
        # a window is cut up to lag_s after its end, and detection looks context_s back
        needed = d.pre_s + d.post_s + max(d.context_s, d.lag_s)
        if self.ring_seconds < needed:
            raise ValueError(
                f"ring_seconds {self.ring_seconds} s cannot hold an event window plus context ({needed:.1f} s)"
            )
        if self.hamiltonian_rate_hz <= 0:
            raise ValueError("hamiltonian_rate_hz must be positive")
        if self.stale_timeout_s <= 0:
            raise ValueError("stale_timeout_s must be positive")


@dataclass
class Outputs:
    events: list[Event] = field(default_factory=list)
    windows: list[EventWindow] = field(default_factory=list)
    recalibrations: list[RecalibrationOutcome] = field(default_factory=list)
    energy: list[EnergySamples] = field(default_factory=list)
    tracked: list[TrackPoint] = field(default_factory=list)
    verdicts: list[EventVerdict] = field(default_factory=list)  # the record on file, event by event

    def extend(self, other: Outputs) -> None:
        self.events += other.events
        self.windows += other.windows
        self.recalibrations += other.recalibrations
        self.energy += other.energy
        self.tracked += other.tracked
        self.verdicts += other.verdicts

    def light(self) -> Outputs:
        """The same outputs without their bulk arrays (windows' samples, all but the last energy
        sample), for a running summary that must not grow with the length of a replay."""
        # copies, not slices: a slice of an array keeps the whole of it alive (a 30 min replay held
        # 130 MB of windows through their empty views)
        windows = [w.light() for w in self.windows]
        energy = [
            EnergySamples(*(getattr(e, f)[-1:].copy() for f in EnergySamples.__dataclass_fields__))
            for e in self.energy[-1:]
        ]
        recalibrations = [dataclasses.replace(r, result=r.result and r.result.light()) for r in self.recalibrations]
        return Outputs(list(self.events), windows, recalibrations, energy, list(self.tracked), list(self.verdicts))


RECORDER_STREAM_NAMES = frozenset(s.name for s in RECORDER_STREAMS)
RECORDER_CHANNELS_OF = {s.name: s.channels for s in RECORDER_STREAMS}


class MonitorPipeline:
    def __init__(self, settings: PipelineSettings | None = None) -> None:
        self.settings = s = settings or PipelineSettings()
        self.aligner = self._new_aligner()
        self.ring = RingBuffer(int(s.ring_seconds * NS // s.period_ns), CHANNELS, s.period_ns)
        self.recorder = RecorderBuffer(s.ring_seconds, not_recorded=s.not_recorded)
        self.detector = Detector(self.ring, s.period_ns, s.detector)
        # in memory (a replay without --store) the store keeps what a recalibration can read, the
        # newest windows of each kind: enough for ready() as long as that is no fewer than it asks
        retain = s.policy.latest_per_kind if s.store_path == ":memory:" else None
        if retain is not None and retain < max(s.policy.min_swing_events, s.policy.min_step_events):
            retain = None
        self.store = EventStore(s.store_path, unit=s.unit or None, retain_per_kind=retain)
        self.recalibrator = Recalibrator(self.store, s.policy, s.identify, controls=s.control_systems)
        self.recalibrator.last_good = s.initial_parameters
        self.markers: list[ScenarioInfo] = []  # a recording's scenario markers: they name the events
        self.tracker: SlidingTracker | None = None
        self.samples_in = 0
        self._segment = 0
        self._energy_slot: int | None = None
        self._energy_done_ns: int | None = None  # stream time up to which the Hamiltonian is computed
        self._energy_params = s.initial_parameters  # the set in force, as polled (never mid-run)
        self._energy_applied: set[int] = set()  # outcomes (by start time) already taken over
        self._hold_limit_ns = int((s.ring_seconds - s.detector.context_s) * NS)
        self.latest_ns: int | None = None
        # the unit's record on file, checked against every usable window (None: not asked for)
        self.record_check: RecordCheck | None = None

    # -- input ---------------------------------------------------------------------------
    def ingest(self, stream: str, t0_ns: int, period_ns: int, arrays: dict, receive_ns: int | None = None) -> None:
        if stream in RECORDER_STREAM_NAMES:  # beside the grid: kept for the windows, never waited for
            self.recorder.ingest(stream, t0_ns, period_ns, arrays, receive_ns)
        else:
            self.aligner.ingest(stream, t0_ns, period_ns, arrays, receive_ns)
        self.samples_in += sum(len(a) for a in arrays.values())

    def ingest_message(
        self, stream: str, t0_ns: int, period_ns: int, arrays: dict, receive_ns: int | None = None
    ) -> None:
        """A sensor block as a ROS message carries it: a zero stamp is an unset clock, not a time."""
        if int(t0_ns) == 0 and stream not in RECORDER_STREAM_NAMES:  # the recorder's buffer counts its own
            h = self.aligner.health[stream]
            n = len(next(iter(arrays.values()))) if arrays else 0
            h.messages += 1
            h.samples += n
            h.zero_stamps += n
            return
        self.ingest(stream, t0_ns, period_ns, arrays, receive_ns)

    def ingest_runs(self, runs: Sequence[Run]) -> bool:
        """Runs of messages as :meth:`ingest_message` would take them one by one, or False and
        nothing taken (see :meth:`Aligner.take_runs`; a recorder's runs go in message by message)."""
        recorder = [r for r in runs if r.stream in RECORDER_STREAM_NAMES]
        if not self.aligner.take_runs([r for r in runs if r.stream not in RECORDER_STREAM_NAMES]):
            return False
        for r in recorder:
            channels = RECORDER_CHANNELS_OF[r.stream]
            a = 0
            for k in r.lengths:
                self.ingest_message(
                    r.stream,
                    r.t0_ns + a * r.period_ns,
                    r.period_ns,
                    {c: r.x[a : a + k, j] for j, c in enumerate(channels)},
                )
                a += k
        self.samples_in += sum(r.x.size for r in runs if r.stream not in RECORDER_STREAM_NAMES)
        return True

    def add_marker(self, marker: ScenarioInfo) -> None:
        self.markers.append(marker)

    # -- processing ---------------------------------------------------------------------------
    @property
    def parameters(self) -> GeneratorParameters | None:
        return self.recalibrator.last_good

    def process(self, *, final: bool = False) -> Outputs:
        out = Outputs()
        for block in self.aligner.pull(final=final):
            if block.segment != self._segment:
                self._segment = block.segment
                late_events, pending = self.detector.flush()
                for e in late_events:
                    self._label(e)
                out.events += late_events
                for w in pending:
                    w.usable, w.reason = False, "the clock jumped (new segment) before the window was complete"
                self._store(pending, out)
                self._energy_upto(self.latest_ns, out)  # what the old segment still owes, if in hand
                self.ring.clear()
                self.recorder.clear()
                self.detector.reset(block.segment)
                if self.tracker is not None:
                    self.tracker.reset()
                self._energy_slot = None
                self._energy_done_ns = None
            held = self.recalibrator.open_since_ns
            if held is not None and int(block.t_ns[-1]) - held >= self._hold_limit_ns:
                # the Hamiltonian's held samples would leave the ring before the run's outcome
                # arrives (playback far faster than real time): wait for it, start nothing new
                self.recalibrator.join()
                out.recalibrations += self.recalibrator.poll(None)
                self._energy_upto(self.latest_ns, out)
            self.ring.append(block.t_ns, block.values)
            self.latest_ns = int(block.t_ns[-1])
            self._track(block.t_ns, block.values, out)
            events, windows = self.detector.update() if self.settings.detect else ([], [])
            for e in events:
                self._label(e)
            out.events += events
            self._store(windows, out)
        if final and self.settings.detect:
            late_events, rest = self.detector.flush()
            for e in late_events:
                self._label(e)
            out.events += late_events
            self._store(rest, out)
        if final and self.settings.auto_recalibrate:
            if self.latest_ns is not None:
                out.recalibrations += self.recalibrator.finish(self.latest_ns)
        else:
            out.recalibrations += self.recalibrator.poll(self.latest_ns)
        self._against_record(out.recalibrations)
        self._energy_upto(self.latest_ns, out)
        return out

    def _against_record(self, outcomes: Sequence[RecalibrationOutcome]) -> None:
        """Each recalibration's determined parameters against the record on file (its drift)."""
        if self.record_check is None:
            return
        for r in outcomes:
            found = r.result.estimates if r.accepted and r.result is not None else r.determined
            if found:
                self.record_check.compare(found)

    def add_window(self, window: EventWindow) -> Outputs:
        """A window cut elsewhere (by the ingest node): label it, store it, maybe recalibrate. Its
        samples are judged as the detector judges its own, on this deployment's channels."""
        out = Outputs()
        stale = stale_data(window.values, self.settings.not_recorded) if window.usable else ""
        if stale:
            window.usable, window.reason = False, stale
        if not window.event.name:
            self._label(window.event)
        self._store([window], out)
        return out

    def recalibrate(self) -> str:
        """On demand (the ~/recalibrate service): run now with the latest events."""
        return self.recalibrator.request(self.latest_ns or 0, force=True)

    def reset(self) -> None:
        """Forget buffered data and stored events (the ~/reset service); parameters are kept."""
        self.aligner = self._new_aligner()
        self.ring.clear()
        self.recorder = RecorderBuffer(self.settings.ring_seconds, not_recorded=self.settings.not_recorded)
        self.detector = Detector(self.ring, self.settings.period_ns, self.settings.detector)
        self.store.clear()
        if self.tracker is not None:
            self.tracker.reset()
        self._segment = 0
        self._energy_slot = None
        self._energy_done_ns = None

    def close(self) -> None:
        self.recalibrator.shutdown()
        self.store.close()

    @property
    def health(self) -> dict[str, StreamHealth]:
        """Every sensor stream's health, and a recorder's stream once it has sent anything: it is
        optional (a deployment without one loses nothing), but one that stops is stale."""
        kept = {n: h for n, h in self.recorder.health.items() if h.messages}
        health = self.aligner.health | kept if kept else self.aligner.health
        marked = [(m.start_ns, m.end_ns) for m in self.markers]
        for h in health.values():
            h.mark_pauses(marked)
        return health

    def status(self, name: str, now_ns: int | None = None) -> tuple[Level, str]:
        """One stream's diagnostic level and message, stale judged on both clocks."""
        return self.health[name].status(
            now_ns, stream_now_ns=self.aligner.stream_now_ns, stale_ns=self.aligner.stale_ns
        )

    def configure(self, settings: PipelineSettings) -> None:
        """Run-time settings changed (a ROS parameter): hand each part its share."""
        self.settings = settings
        self.detector.settings = settings.detector
        self.recalibrator.policy = settings.policy
        self.aligner.stale_ns = int(settings.stale_timeout_s * NS)
        if not settings.tracking_enabled:
            self.tracker = None

    def _track(self, t_ns: np.ndarray, values: np.ndarray, out: Outputs) -> None:
        s = self.settings
        if not s.tracking_enabled:
            return
        if self.tracker is None:
            base = s.tracking_base or self.parameters
            if base is None:
                return
            self.tracker = SlidingTracker(base, s.period_ns, s.tracking)
            t_ns, values = self.ring.window(self.ring.oldest_ns, self.latest_ns)  # type: ignore[arg-type]
        out.tracked += self.tracker.update(t_ns, values)

    def _new_aligner(self) -> Aligner:
        s = self.settings
        return Aligner(
            s.period_ns,
            stale_ns=int(s.stale_timeout_s * NS),
            expected_rates_hz=s.expected_rates_hz,
            not_recorded=s.not_recorded,
        )

    # -- helpers ----------------------------------------------------------------------------
    def _label(self, e: Event) -> None:
        for m in self.markers:
            if m.start_ns <= e.inception_ns <= m.end_ns:
                e.name, e.role, e.generator_damping = m.name, m.role, m.generator_damping
                e.regulator, e.reference_step = m.regulator, m.reference_step
                return

    def _store(self, windows: list[EventWindow], out: Outputs) -> None:
        for w in windows:
            if not w.event.name:
                # its marker came after the event was detected (on ROS a marker and the samples
                # travel on two topics, and at 20x a loaded machine delivered a torque step's
                # marker late): the window, seconds of stream time later, is labelled all the same,
                # so it is played as replay plays it (a verdict differed by 1 % on the launch)
                self._label(w.event)
            if not w.recorded:
                w.recorded = self.recorder.columns(w.t_ns)
            if self.settings.keep_windows:
                self.store.add(w)
            out.windows.append(w)
            self._check_record(w, out)
            if w.usable and self.settings.auto_recalibrate and w.event.role == "identify":
                self.recalibrator.request(int(w.t_ns[-1]) if len(w.t_ns) else w.event.inception_ns)

    def _check_record(self, w: EventWindow, out: Outputs) -> None:
        """The window played into the record on file; its verdict kept with the window."""
        check = self.record_check
        if check is None or not w.usable:
            return
        for verdict in check.check(w, self.settings.identify.f_nominal_hz):
            out.verdicts.append(verdict)  # an earlier event's, played again, replaces its verdict
            if self.settings.keep_windows:
                self.store.add_verdict(verdict.event_id, check.describe, verdict.passed, verdict.as_json())

    def _energy_upto(self, latest_ns: int | None, out: Outputs) -> None:
        """The Hamiltonian at the set rate, each sample with the set in force at its stamp.

        A recalibration runs in a worker; its outcome applies from the stream time it was
        started, as if it were instantaneous. So samples from that time on wait (in the ring)
        until the outcome is polled: the published values and their count do not depend on how
        fast the machine or the playback is.
        """
        if latest_ns is None:
            return
        held = self.recalibrator.open_since_ns
        limit = latest_ns if held is None else min(latest_ns, held - 1)
        # each polled outcome takes over at the stream time its run started
        for r in sorted((r for r in out.recalibrations if r.accepted), key=lambda r: r.stream_time_ns):
            if r.stream_time_ns in self._energy_applied:
                continue
            self._energy_applied.add(r.stream_time_ns)
            self._energy_span(min(limit, r.stream_time_ns - 1), out)
            self._energy_params = r.parameters
        self._energy_span(limit, out)

    def _energy_span(self, limit: int, out: Outputs) -> None:
        start = self._energy_done_ns + 1 if self._energy_done_ns is not None else self.ring.oldest_ns
        if start is None or limit < start:
            return
        params = self._energy_params
        self._energy_done_ns = limit
        if params is None:
            return
        t_ns, values = self.ring.window(start, limit)
        if len(t_ns) == 0:
            return
        interval = int(NS / self.settings.hamiltonian_rate_hz)
        slots = t_ns // interval
        first = np.flatnonzero(
            np.diff(np.concatenate(([self._energy_slot if self._energy_slot is not None else slots[0] - 1], slots))) > 0
        )
        self._energy_slot = int(slots[-1])
        if first.size == 0:
            return
        rows = values[first]
        ok = np.isfinite(rows).all(axis=1)
        if ok.any():
            out.energy.append(energy(t_ns[first][ok], rows[ok], params))
