"""T'_d0 from no-load tests: the open-circuit machine's terminal voltage follows its field.

With no stator current the fourth-order model's d axis (7) is a first-order lag and the
terminal voltage is its flux, V_t = E'_q (11)-(12) with I = 0):

    T'_d0 dV_t/dt = k E_fd - V_t,

where k is 1 when E_fd is in the machine's per unit (IEEE 115's air-gap-line base) and absorbs
what the field base's calibration missed otherwise (it is reported). A field step at no load is
the commissioning test IEEE 115 (10.3) names for T'_d0. For one trial T'_d0 the response is
linear in k and in each test's free initial flux, so the fit is one bounded search over
log T'_d0 with linear least squares inside (variable projection, as stage 3's), and the
standard deviations are cluster-robust on 1 s blocks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from phid_ros.errors import StageError
from phid_ros.ident.results import STD_CALIBRATION, Estimate, flag
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.stage3 import T_D0_BOUNDS
from phid_ros.ident.terminal import at_no_load
from phid_ros.ident.uncertainty import block_ids, cluster_robust_cov
from phid_ros.numerics import first_order_response, free_decay

Array = NDArray[np.float64]
BLOCK_SECONDS = 1.0
MIN_FIELD_STEP = 0.01  # pu of E_fd: a no-load window whose field does not move carries no T'_d0


class OpenCircuitError(StageError):
    """No no-load test with a field step to fit."""


@dataclass
class OpenCircuitResult:
    T_d0_prime: Estimate
    field_gain: float  # k: V_t per unit of E_fd as recorded at no load (1 on the air-gap line)
    scenarios: list[str]
    rms_pu: float
    problems: list[str] = field(default_factory=list)


def no_load_tests(scenarios: Sequence[ScenarioData]) -> list[ScenarioData]:
    """The identification scenarios at no load whose field moves."""
    out = []
    for s in scenarios:
        if s.role != "identify" or not s.has("v_t", "v_f") or not at_no_load(s):
            continue
        if float(np.ptp(s["v_f"])) - 6 * float(np.std(np.diff(s["v_f"]))) > MIN_FIELD_STEP:
            out.append(s)
    return out


def _design(scs: Sequence[ScenarioData], tau: float) -> tuple[Array, Array, list[int]]:
    """(V_t stacked, columns [L[E_fd], one decay per test]) for one T'_d0."""
    cols, ys, lengths = [], [], []
    m = len(scs)
    for j, s in enumerate(scs):
        n = s.n
        block = np.zeros((n, 1 + m))
        block[:, 0] = first_order_response(s["v_f"], tau, s.dt)
        block[:, 1 + j] = free_decay(n, tau, s.dt)
        cols.append(block)
        ys.append(s["v_t"])
        lengths.append(n)
    return np.concatenate(ys), np.vstack(cols), lengths


def open_circuit(scenarios: Sequence[ScenarioData]) -> OpenCircuitResult:
    scs = no_load_tests(scenarios)
    if not scs:
        raise OpenCircuitError("no no-load test with a field step (V_t and E_fd recorded, no stator current)")

    def fit(log_tau: float) -> tuple[float, Array, Array, Array, list[int]]:
        y, x, lengths = _design(scs, math.exp(log_tau))
        coef = np.asarray(np.linalg.lstsq(x, y, rcond=None)[0], dtype=np.float64)
        r = y - x @ coef
        return float(r @ r), coef, r, x, lengths

    lo, hi = (math.log(b) for b in T_D0_BOUNDS)
    grid = np.linspace(lo, hi, 13)
    vals = [fit(g)[0] for g in grid]
    k = int(np.argmin(vals))
    best = minimize_scalar(
        lambda g: fit(g)[0],
        bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
        method="bounded",
        options={"xatol": 1e-7},
    )
    log_tau = float(best.x)
    _, coef, r0, x0, lengths = fit(log_tau)
    h = 1e-5
    _, _, r1, _, _ = fit(log_tau + h)
    # the tau column profiled over the nuisance (each test's decay refitted), beside the k column
    jac = np.column_stack([x0[:, 0], (r0 - r1) / h])
    blocks = block_ids(lengths, max(1, int(round(BLOCK_SECONDS / scs[0].dt))))
    cov = cluster_robust_cov(jac, r0, blocks)
    tau = math.exp(log_tau)
    sd_tau = STD_CALIBRATION * tau * math.sqrt(max(cov[1, 1], 0.0))
    est = flag(Estimate(tau, sd_tau, drivers=[s.name for s in scs][:3]), "T_d0_prime")
    est.add_note("T'_d0 from no-load field steps (open circuit: V_t follows E_fd through T'_d0)")
    problems = []
    if not T_D0_BOUNDS[0] * 1.001 < tau < T_D0_BOUNDS[1] * 0.999:
        est.at_bound = True
        est.disqualify(f"T_d0_prime = {tau:.4g} s is at its search bound {T_D0_BOUNDS}")
    spread = _between_tests(scs, tau)
    if spread is not None and spread[0] > sd_tau:
        est.std = spread[0]
        est.add_note(f"std from the spread between the tests' own T'_d0 ({spread[1]})")
    curvature = saturation_seen(scs)
    if curvature is not None:
        est.disqualify(
            f"the no-load tests reach the saturated part of the open-circuit curve ({curvature}): a field "
            "step's time constant there is T'_d0 over the curve's incremental slope, not T'_d0"
        )
    gain = float(coef[0])
    if abs(gain - 1.0) > 0.05:
        problems.append(
            f"open circuit: V_t settles at {gain:.3f} x E_fd, not E_fd: the field base is off by "
            f"{100 * (gain - 1):+.1f} % (or the machine is saturated at this voltage)"
        )
    return OpenCircuitResult(est, gain, [s.name for s in scs], math.sqrt(float(r0 @ r0) / len(r0)), problems)


SATURATION_GAP = 0.03  # the field per volt differing by more than this between no-load plateaus


def no_load_plateaus(scs: Sequence[ScenarioData]) -> list[tuple[float, float, str]]:
    """(V_t, E_fd as recorded, scenario) over each no-load test's steady parts, before and after."""
    out = []
    for s in scs:
        for sl in (s.pre_slice(), s.steady_slice()):
            v, e = s["v_t"][sl], s["v_f"][sl]
            if len(v) < 10 or float(np.median(v)) < 0.2:  # a de-excited machine's remanence is no point
                continue
            out.append((float(np.mean(v)), float(np.mean(e)), s.name))
    return out


@dataclass
class FieldBase:
    """The recorded E_fd's base against the machine's, from the no-load plateaus: the machine's
    E_fd is ``scale`` x the recorded one."""

    scale: float
    v_t: Array  # the plateaus' V_t
    recorded: Array  # and their recorded E_fd
    scatter: float  # the plateaus' largest relative distance from the fitted curve


def field_base(scs: Sequence[ScenarioData], open_circuit: Callable[[Array], Array] | None = None) -> FieldBase | None:
    """The scale that puts the recorded E_fd on the machine's base: at a no-load plateau the
    machine's E_fd is ``open_circuit(V_t)`` (a record's open-circuit curve; the air-gap line,
    E_fd = V_t, without one), fitted through the origin over every plateau of the no-load tests
    among ``scs``. None without a no-load test."""
    tests = [s for s in scs if s.has("v_t", "v_f") and at_no_load(s)]
    pts = no_load_plateaus(tests)
    if not pts:
        return None
    v_t, recorded = np.array([p[0] for p in pts]), np.array([p[1] for p in pts])
    machine = open_circuit(v_t) if open_circuit is not None else v_t
    k = float(machine @ recorded / (recorded @ recorded))
    return FieldBase(k, v_t, recorded, float(np.max(np.abs(k * recorded / machine - 1.0))))


def saturation_seen(scs: Sequence[ScenarioData]) -> str | None:
    """The figures that show the tests on a curved open-circuit characteristic, or None: the field
    per volt (E_fd / V_t) at the no-load plateaus differs by more than SATURATION_GAP. On the
    air-gap line it is one number whatever the field's base."""
    pts = no_load_plateaus(scs)
    if len(pts) < 2:
        return None
    ratio = np.array([e / v for v, e, _ in pts])
    lo, hi = int(np.argmin(ratio)), int(np.argmax(ratio))
    if ratio[hi] / ratio[lo] - 1.0 <= SATURATION_GAP:
        return None
    return (
        f"E_fd/V_t {ratio[lo]:.4g} at V_t {pts[lo][0]:.3f} pu, {ratio[hi]:.4g} at V_t {pts[hi][0]:.3f} pu: "
        f"{100 * (ratio[hi] / ratio[lo] - 1):+.1f} %"
    )


def _between_tests(scs: Sequence[ScenarioData], tau: float) -> tuple[float, str] | None:
    """(the std of the mean of the tests' own T'_d0, their values): what the choice of test moves
    the answer by, which the pooled fit's residuals do not see."""
    if len(scs) < 2:
        return None
    own = []
    for s in scs:

        def sse(log_tau: float, s: ScenarioData = s) -> float:
            y, x, _ = _design([s], math.exp(log_tau))
            r = y - x @ np.linalg.lstsq(x, y, rcond=None)[0]
            return float(r @ r)

        lo, hi = (math.log(b) for b in T_D0_BOUNDS)
        own.append(math.exp(float(minimize_scalar(sse, bounds=(lo, hi), method="bounded").x)))
    values = ", ".join(f"{v:.3g} s" for v in own)
    return float(np.std(own, ddof=1) / math.sqrt(len(own))), values
