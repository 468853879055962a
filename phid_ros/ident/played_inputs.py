"""The boundary signals a play-in is driven by, with the sensor noise taken out of V_t and theta_t.

A play-in (:mod:`phid_ros.ident.validation`, :mod:`phid_ros.ident.plant_playin`) drives the model
with the measured terminal voltage. V_t and theta_t reach the simulated currents, P and Q
algebraically (through V_d, V_q), so their noise is not averaged out by the machine's time
constants as the noise on P_m and V_f is: it is an error in the variables the fit regresses on.
On a linear machine that only adds scatter, but a saturated machine turns it into an offset the
fit absorbs in X_d and T'_d0 (STEPS's saturated GENSAL, 0.002 pu of V_t noise played in raw:
X_d +1.6 %, T'_d0 +3.1 %; the same set with V_t and theta_t clean: +0.5 %, +1.1 %).

The paper plays the raw samples in. Here each segment between switching instants (the event,
the clearing, further steps of a long window) is low-passed with zero phase, so no edge of a
step is smeared and no delay is added; the segment's ends are matched by odd extension. The
cut-off, 60 Hz, sits well above what the model's fastest circuit (a damper, T'' of 20 ms and
more: a corner below 8 Hz) puts into V_t, and leaves a third of a 1 kHz recorder's white noise.
Measured on STEPS's GENSAL without noise: the played-in V_t moves by at most 1.5e-4 pu, theta_t
by 3e-4 rad, both at a fault's first samples; with its noise, X_d +0.6 % and T'_d0 +1.3 %.

Only a fit reads them (:func:`phid_ros.ident.plant_playin.residual_matrix`). A score plays the
measurements in and removes their white noise from the residual; the noise smoothing leaves is
correlated over a few rows, and a score would count it as unexplained.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from phid_ros.ident.scenario import ScenarioData

Array = NDArray[np.float64]

SMOOTHED = ("v_t", "theta_t")  # the inputs with an algebraic path to the outputs
CUTOFF_HZ = 60.0
ORDER = 4
# Where a segment starts: the largest jump from SNAP_BEFORE samples before a switching instant
# to SNAP_AFTER_S after it. The instant is found on V_t; a recorder's own jump may land a sample
# either side, and a sensor's latency (a PMU's angle 20 ms late) moves that channel's jump later.
SNAP_BEFORE = 2
SNAP_AFTER_S = 0.03


def played_input(scenario: ScenarioData, name: str) -> Array:
    """Channel ``name`` of ``scenario`` as a fit's play-in reads it (kept with the scenario)."""
    if name not in SMOOTHED:
        return scenario[name]
    smooth = smoothed_angle if name == "theta_t" else smoothed
    return scenario.derived(
        ("played_input", name), lambda: smooth(scenario[name], scenario.dt, scenario.switching, CUTOFF_HZ)
    )


def smoothed_angle(x: Array, dt: float, switching: list[int], cutoff_hz: float) -> Array:
    """An angle :func:`smoothed` across its wraps: a recorder's angle may jump by 2 pi inside a
    segment, which a low-pass would spread over a dozen samples of nonsense. Each sample keeps the
    branch it was recorded on (the play-in reads it through sine and cosine either way)."""
    if not np.all(np.isfinite(x)):
        return smoothed(x, dt, switching, cutoff_hz)
    unwrapped = np.unwrap(x)
    return smoothed(unwrapped, dt, switching, cutoff_hz) - (unwrapped - x)


def smoothed(x: Array, dt: float, switching: list[int], cutoff_hz: float) -> Array:
    """``x`` low-passed with zero phase inside each segment between ``switching`` samples.

    A segment too short for the filter, or holding a non-finite sample (a channel the recording
    did not carry), is returned as measured.
    """
    nyquist = 0.5 / dt
    if cutoff_hz >= 0.8 * nyquist:  # a slow recorder (a PMU's 50 reports/s) has no band to take out
        return x
    sos = signal.butter(ORDER, cutoff_hz / nyquist, output="sos")
    out = np.array(x, dtype=np.float64)
    after = round(SNAP_AFTER_S / dt)
    starts = {_snapped(x, k, nxt, after) for k, nxt in zip(switching, [*switching[1:], len(x)], strict=True)}
    edges = sorted({0, *starts, len(x)})
    pad = 3 * (2 * len(sos) + 1)  # sosfiltfilt's own pad (3 x the filter's length): a segment must be longer
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        seg = x[a:b]
        if b - a <= 2 * pad or not np.all(np.isfinite(seg)):
            continue
        out[a:b] = signal.sosfiltfilt(sos, seg, padtype="odd", padlen=pad)
    return out


def _snapped(x: Array, k: int, following: int, after: int) -> int:
    """The sample after the largest jump near switching instant ``k`` (before the ``following`` one)."""
    lo, hi = max(1, k - SNAP_BEFORE), min(len(x) - 1, k + after, following - 1)
    if hi < lo:
        return k
    jumps = np.abs(np.diff(x[lo - 1 : hi + 1]))
    if not np.all(np.isfinite(jumps)):
        return k
    return lo + int(np.argmax(jumps))
