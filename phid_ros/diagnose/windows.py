"""The data a diagnosis fits and holds out: event windows, the split, each channel's noise, and what it refuses."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from phid_ros.diagnose.localise import noise_std
from phid_ros.diagnose.options import DiagnoseError
from phid_ros.ident.plant_playin import OUTPUTS
from phid_ros.ident.scenario import ScenarioData


def window(s: ScenarioData, pre_s: float, post_s: float) -> ScenarioData:
    """The scenario cut to [event - pre_s, event + post_s]."""
    a = max(0, s.k_event - int(round(pre_s / s.dt)))
    b = min(s.n, s.k_event + int(round(post_s / s.dt)))
    return s.rows(a, b)


def split(scenarios: Sequence[ScenarioData], per_kind: int) -> tuple[list[ScenarioData], list[ScenarioData]]:
    """Fit scenarios (per kind the smallest and the largest by name order) and held-out ones."""
    ident = [s for s in scenarios if s.role == "identify"]
    fit_set: list[ScenarioData] = []
    for kind in sorted({s.kind for s in ident}):
        same = sorted((s for s in ident if s.kind == kind), key=lambda s: s.name)
        pick = np.unique(np.round(np.linspace(0, len(same) - 1, min(per_kind, len(same)))).astype(int))
        fit_set.extend(same[i] for i in pick)
    held = [s for s in scenarios if s.role == "validate"]
    if not held:
        held = [s for s in ident if s not in fit_set]
    return fit_set, held


def channel_sigma(scenarios: Sequence[ScenarioData]) -> dict[str, float]:
    return {c: max(float(np.median([noise_std(s[c]) for s in scenarios])), 1e-12) for c in OUTPUTS}


def pre_event(windows: Sequence[ScenarioData]) -> dict[str, float]:
    """Mean pre-event terminal quantities over the windows (one operating point)."""
    return {
        c: float(np.mean([np.mean(w[c][w.pre_slice()]) for w in windows]))
        for c in ("v_d", "v_q", "i_d", "i_q", "v_f", "p_m")
    }


def check_measurements(scenarios: Sequence[ScenarioData], sigma: Mapping[str, float]) -> None:
    """The diagnosis weighs residuals by each channel's white sensor noise, estimated from first
    differences. Phasors measured over a window (a one-cycle DFT) have correlated noise whose
    first differences understate it, and the window smears each switching into something that
    looks like fast physics: tried on COMTRADE waveforms of a plain fourth-order machine, it
    named subtransient dynamics and a 4 ms excitation latency that were not there. Refused
    until the play-in models the window, rather than publishing invented effects."""
    windowed = sorted({s.measurement_window_s for s in scenarios if s.measurement_window_s > 0})
    if windowed:
        raise DiagnoseError(
            f"the samples were measured over a {1e3 * windowed[0]:g} ms window (phasors of a DFT or a PMU): "
            "the diagnosis assumes sample-by-sample measurements with white noise and would name effects "
            "the window makes; identify these recordings, diagnose sample-by-sample ones"
        )
    flat = [c for c, v in sigma.items() if v <= 1e-12]
    if flat:
        raise DiagnoseError(
            f"channel(s) {', '.join(flat)} show no sample-to-sample noise (quantised or smoothed below their "
            "resolution): the diagnosis cannot weigh their residuals"
        )
