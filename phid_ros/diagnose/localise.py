"""Gap localisation: where the identified model and the measurement disagree.

The identified model is driven by the measured boundary signals (V_t, theta_t,
P_m, V_f; the play-in of :mod:`phid_ros.ident.validation`) and its outputs
(omega, delta, I_d, I_q, P_e, Q_e) are compared with the measured ones. Each
channel's residual is normalised by that channel's sensor noise (estimated from
the data), and the noise's own share is removed, so what is reported is the
*unexplained* power: about zero for a model that lacks nothing. It is broken
down by scenario and kind, by phase (pre-event, during the fault, first second
after the event or clearing, settling, steady state), by channel and by
frequency band.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.validation import play_in, play_in_samples
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ
from phid_ros.model.parameters import GeneratorParameters

Array = NDArray[np.float64]
OUTPUTS = ("omega", "delta", "i_d", "i_q", "p_e", "q_e")
PHASES = ("pre_event", "during_fault", "first_second", "settling", "steady_state")
BANDS: tuple[tuple[str, float, float], ...] = (
    ("slow (< 0.5 Hz)", 0.0, 0.5),
    ("electromechanical (0.5-3 Hz)", 0.5, 3.0),
    ("fast (3-20 Hz)", 3.0, 20.0),
    ("torsional and above (> 20 Hz)", 20.0, np.inf),
)


def noise_std(x: Array) -> float:
    """Sensor-noise standard deviation from first differences (robust MAD; signals barely move per sample)."""
    d = np.diff(x)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


@dataclass
class GapReport:
    """Unexplained residual power (in units of each channel's noise variance) and where it sits."""

    by_scenario: dict[str, float] = field(default_factory=dict)
    by_kind: dict[str, float] = field(default_factory=dict)
    by_phase: dict[str, float] = field(default_factory=dict)
    by_channel: dict[str, float] = field(default_factory=dict)
    by_band: dict[str, float] = field(default_factory=dict)
    rmse: dict[str, float] = field(default_factory=dict)  # per channel, in its own unit

    @property
    def total(self) -> float:
        return float(sum(self.by_channel.values()))

    def top(self, part: str, k: int = 3) -> list[tuple[str, float]]:
        d = getattr(self, part)
        return sorted(d.items(), key=lambda kv: -kv[1])[:k]

    def as_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items()} | {"total": self.total}


def _phases(s: ScenarioData, idx: Array) -> dict[str, NDArray[np.bool_]]:
    end = s.k_clear if s.k_clear is not None else s.k_event
    one_s = int(round(1.0 / s.dt))
    steady = int(round(0.8 * s.n))
    return {
        "pre_event": idx < s.k_event,
        "during_fault": (idx >= s.k_event) & (idx < end),
        "first_second": (idx >= end) & (idx < end + one_s),
        "settling": (idx >= end + one_s) & (idx < steady),
        "steady_state": idx >= max(steady, end + one_s),
    }


def localise(
    scenarios: Sequence[ScenarioData], params: GeneratorParameters, f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ
) -> GapReport:
    rep = GapReport()
    rep.by_phase = {p: 0.0 for p in PHASES}
    rep.by_band = {b[0]: 0.0 for b in BANDS}
    sq_err: dict[str, list[float]] = {c: [] for c in OUTPUTS}
    trajs = play_in(list(scenarios), [params], f_nominal_hz)
    for s, tr in zip(scenarios, trajs):
        idx = play_in_samples(s)[: len(tr.t)]
        phases = _phases(s, idx)
        h = float(tr.t[1] - tr.t[0])
        scen_total = 0.0
        for c in OUTPUTS:
            meas = s[c][idx]
            sim = getattr(tr, c)[:, 0]
            r = sim - meas
            sq_err[c].extend((r**2).tolist())
            sigma2 = max(noise_std(s[c]) ** 2, 1e-18)
            # unexplained power per sample, in noise variances: the noise's own share (1) removed
            excess = r**2 / sigma2 - 1.0
            total = float(np.sum(excess)) / len(r)
            scen_total += max(total, 0.0)
            rep.by_channel[c] = rep.by_channel.get(c, 0.0) + max(total, 0.0)
            for name, mask in phases.items():
                if mask.any():
                    rep.by_phase[name] += max(float(np.sum(excess[mask])) / len(r), 0.0)
            # frequency bands of the residual (mean removed: an offset is "slow")
            spec = np.abs(np.fft.rfft(r)) ** 2
            freqs = np.fft.rfftfreq(len(r), h)
            noise_floor = sigma2 * len(r)  # white noise's flat share per bin (Parseval, one-sided)
            for name, lo, hi in BANDS:
                band = (freqs >= lo) & (freqs < hi)
                if band.any():
                    rep.by_band[name] += max(float(np.sum(spec[band] - noise_floor)) / (len(r) ** 2 * sigma2), 0.0)
        rep.by_scenario[s.name] = scen_total
        rep.by_kind[s.kind] = rep.by_kind.get(s.kind, 0.0) + scen_total
    rep.rmse = {c: float(np.sqrt(np.mean(v))) for c, v in sq_err.items()}
    return rep
