"""Sliding-window tracking of slow parameter drift (the paper's future work, section 5.2).

Every ``hop_s`` of stream time the tracker runs stage 1 (H, D) and stage 3
(X'_d, X'_q, T'_d0, T'_q0), the identification's own registered stages
(``ident/stages.py``) with the tracker's settings, on the last ``window_s`` of aligned data, with the
steps inside the window (found by the batch detector) as switching instants and
the time-constant searches warm-started around the previous hop's values.
X_d and X_q come from the base set (the last recalibration): ambient data has no
settled steady states for stage 2. Each hop publishes estimates with standard
deviations and identifiability; a parameter that leaves the confidence band
around its reference (the first window's estimate) for ``alarm_after``
consecutive hops raises a drift alarm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import StageError
from phid_ros.ident import stage3
from phid_ros.ident.results import Estimate
from phid_ros.ident.scenario import ScenarioData, find_events
from phid_ros.ident.stages import SwingRegression, VariableProjection
from phid_ros.model.channels import CHANNELS, Frame
from phid_ros.model.conventions import NS
from phid_ros.model.parameters import SYMBOLS, GeneratorParameters
from phid_ros.stream.ring import RingBuffer

TRACKED = ("H", "D", "X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime")


@dataclass(frozen=True)
class TrackerSettings:
    window_s: float = 300.0
    hop_s: float = 60.0
    drift_sigmas: float = 4.0
    alarm_after: int = 2
    warm_start_span: float = 0.4  # search +-40 % around the previous hop's time constants

    def __post_init__(self) -> None:
        if not 0 < self.hop_s <= self.window_s:
            raise ValueError("need 0 < hop_s <= window_s")


@dataclass
class TrackPoint:
    t_ns: int  # end of the window
    estimates: dict[str, Estimate]
    alarms: list[str]
    problems: list[str] = field(default_factory=list)
    alarmed: list[str] = field(default_factory=list)  # the parameters the alarms are about
    steps: list[tuple[str, int]] = field(default_factory=list)  # (kind, stamp) of the steps in the window

    def value(self, name: str) -> float:
        e = self.estimates.get(name)
        return e.value if e else math.nan


@dataclass
class SlidingTracker:
    base: GeneratorParameters
    period_ns: int = 1_000_000
    settings: TrackerSettings = field(default_factory=TrackerSettings)
    reference: dict[str, Estimate] = field(default_factory=dict)
    history: list[TrackPoint] = field(default_factory=list)
    _ring: RingBuffer | None = None
    _next_hop_ns: int | None = None
    _beyond: dict[str, int] = field(default_factory=dict)
    _alarmed: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        self._ring = RingBuffer(int(self.settings.window_s * NS // self.period_ns) + 1, CHANNELS, self.period_ns)

    def reset(self) -> None:
        """A new segment (clock jump): windows must not span it."""
        assert self._ring is not None
        self._ring.clear()
        self._next_hop_ns = None

    def update(self, t_ns: NDArray[np.int64], values: NDArray[np.float64]) -> list[TrackPoint]:
        ring = self._ring
        assert ring is not None
        window = int(self.settings.window_s * NS)
        out = []
        while len(t_ns):
            if self._next_hop_ns is None:
                self._next_hop_ns = (ring.oldest_ns if ring.oldest_ns is not None else int(t_ns[0])) + window
            # the ring holds one window: feed up to the next hop's end only, so that none of the
            # window is overwritten before the hop reads it, whatever the size of the blocks
            k = max(1, int(np.searchsorted(t_ns, self._next_hop_ns, side="right")))
            ring.append(t_ns[:k], values[:k])
            t_ns, values = t_ns[k:], values[k:]
            while ring.latest_ns is not None and ring.latest_ns >= self._next_hop_ns:
                t, x = ring.window(self._next_hop_ns - window + self.period_ns, self._next_hop_ns)
                out.append(self._hop(t, x))
                self._next_hop_ns += int(self.settings.hop_s * NS)
        return out

    def _hop(self, t: NDArray[np.int64], x: NDArray[np.float64]) -> TrackPoint:
        dt = self.period_ns / NS
        point = TrackPoint(int(t[-1]), {}, [])
        if not np.isfinite(x).all():
            point.problems.append("stale window: gaps in the data; no estimate this hop")
            self.history.append(point)
            return point
        frame = Frame(t, x, self.period_ns)
        found = find_events(frame.columns(), dt)
        steps = [k for _, k, _ in found] + [k_cl for _, _, k_cl in found if k_cl]
        point.steps = [(kind, int(t[k])) for kind, k, _ in found]
        k0 = max(1, int(1.0 / dt))  # a short "pre" stretch for the stages' baselines
        sc = ScenarioData(
            "window",
            "torque_step",
            "identify",
            True,
            frame,
            k_event=k0,
            extra_switching=[k for k in steps if k > k0],
        )
        try:
            point.estimates.update(SwingRegression().run([sc], {}).estimates)
        except StageError as exc:
            point.problems.append(f"stage 1: {exc}")
        prev = self.history[-1] if self.history else None
        span = self.settings.warm_start_span

        def around(name: str, bounds: tuple[float, float]) -> tuple[float, float] | None:
            v = prev.value(name) if prev else math.nan
            if not math.isfinite(v):
                return None
            return max(bounds[0], v * (1 - span)), min(bounds[1], v * (1 + span))

        # the window is ambient data with a few steps: all of it, not 12 s after one event
        state_consistency = VariableProjection(
            window_s=None,
            bounds_d=around("T_d0_prime", stage3.T_D0_BOUNDS),
            bounds_q=around("T_q0_prime", stage3.T_Q0_BOUNDS),
        )
        try:
            out = state_consistency.run([sc], {"X_d": self.base.X_d, "X_q": self.base.X_q})
            point.estimates.update(out.estimates)
            point.problems += out.problems
        except StageError as exc:
            point.problems.append(f"stage 3: {exc}")
        self._check_drift(point)
        self.history.append(point)
        return point

    def _check_drift(self, point: TrackPoint) -> None:
        for name, est in point.estimates.items():
            if not est.identifiable or not math.isfinite(est.std):
                continue
            ref = self.reference.get(name)
            if ref is None:
                self.reference[name] = est
                continue
            # the same plant under the same conditions: a common (errors-in-variables) bias cancels
            band = self.settings.drift_sigmas * math.hypot(est.random_std, ref.random_std)
            if abs(est.value - ref.value) > band:
                self._beyond[name] = self._beyond.get(name, 0) + 1
            else:
                self._beyond[name] = 0
            if self._beyond[name] >= self.settings.alarm_after:
                change = 100 * (est.value / ref.value - 1)
                point.alarms.append(
                    f"{SYMBOLS[name]} drifted {change:+.1f} % from {ref.value:.4g} "
                    f"(beyond {self.settings.drift_sigmas:g} sigma for {self._beyond[name]} hops)"
                )
                self._alarmed.add(name)
                point.alarmed.append(name)

    @property
    def alarmed(self) -> set[str]:
        return set(self._alarmed)
