"""The rotor's position from the terminal quantities, for recordings without a rotor angle.

Fault recorders, excitation controllers and PMUs record V_t, P, Q (or I_t) and at most E_fd:
no rotor angle. The d/q split the stages need is then reconstructed. In steady state (R_a = 0)
the q axis lies on E_Q = V + j X_q I (the phasor diagram of IEEE 115 and of every planning
model's initialisation, :meth:`phid_ros.sim.plant.Plant.steady_state`), so

    delta - theta_t = arg(V + j X_q I).

It is exact at rest, and in transients as long as E'_d = (X_q - X'_q) I_q holds: always for a
salient-pole machine without a q-axis transient winding (X'_q = X_q), and closely for field and
voltage steps, which move I_q little. The same steady states carry X_d and X_q through
E_fd = V_q + X_d I_d: with E_fd recorded, :func:`steady_reactances` fits both (or X_d alone
with X_q held at a datasheet value).

For the swing equation the rotor speed is the reconstructed angle's derivative
(:func:`rotor_speed`). The classical model's stand-in, the speed of the voltage behind X'_d,
swung 22 % less than the rotor on a round-rotor set (X'_q = 1.6 X'_d): it is not used.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from phid_ros.errors import StageError
from phid_ros.ident.constraints import held
from phid_ros.ident.results import Estimate, flag
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.channels import CHANNEL_INDEX, NO_LOAD_CURRENT, Frame, current_of
from phid_ros.model.conventions import omega_s, terminal_to_dq

Array = NDArray[np.float64]
X_Q_SEARCH = (0.2, 4.0)  # pu: the joint fit's search for X_q
MIN_POINTS = 3


class TerminalError(StageError):
    """The terminal quantities cannot give what was asked (too few steady states, no load)."""


def stator_current(s: ScenarioData) -> np.ndarray:
    """The stator current phasor from P, Q and V (the terminal voltage's angle as recorded, 0 if not)."""
    v = s["v_t"] * np.exp(1j * _theta(s))
    return np.conj((s["p_e"] + 1j * s["q_e"]) / v)


def _theta(s: ScenarioData) -> Array:
    theta = s["theta_t"]
    return theta if s.has("theta_t") else np.zeros(s.n)


def current_magnitude(s: ScenarioData) -> Array:
    return current_of({c: s[c] for c in ("p_e", "q_e", "v_t")})


def at_no_load(s: ScenarioData) -> bool:
    """No stator current before or after the event: an open-circuit test."""
    i = current_magnitude(s)
    return bool(np.median(i) < NO_LOAD_CURRENT)


def load_angle(v_t: Array, theta_t: Array, current: np.ndarray, x_q: float) -> Array:
    """delta - theta_t = arg(V + j X_q I) with V at angle theta_t."""
    v = v_t * np.exp(1j * theta_t)
    return np.angle((v + 1j * x_q * current) * np.exp(-1j * theta_t))


def dynamic_load_angle(s: ScenarioData, x_q: float, x_q_prime: float, t_q0_prime: float) -> Array:
    """delta - theta_t with the q-axis transient flux followed through the disturbance.

    With E'_d known the rotor lies where the d component of W = V + j X'_q I equals it,
    delta - arg W = asin(E'_d / |W|), and E'_d follows T'_q0 dE'_d/dt = (X_q - X'_q) I_q - E'_d
    (8) from rest. For a round-rotor machine whose X'_q and T'_q0 the user holds.
    """
    theta = _theta(s)
    current = stator_current(s) * np.exp(-1j * theta)  # against the terminal voltage
    w = s["v_t"] + 1j * x_q_prime * current
    psi, w_abs = np.angle(w), np.abs(w)
    i_abs, phi = np.abs(current), np.angle(current)
    a = math.exp(-s.dt / t_q0_prime)
    k0 = max(1, min(s.k_event, s.n))
    rest = load_angle(s["v_t"][:k0], np.zeros(k0), current[:k0], x_q)
    e_d = float(np.mean(w_abs[:k0] * np.sin(rest - psi[:k0])))  # E'_d at rest: (X_q - X'_q) I_q
    out = np.empty(s.n)
    gain = x_q - x_q_prime
    for k in range(s.n):
        d = psi[k] + math.asin(max(-1.0, min(1.0, e_d / w_abs[k])))
        out[k] = d
        i_q = i_abs[k] * math.cos(d - phi[k])
        e_d = a * e_d + (1.0 - a) * gain * i_q
    return out


def with_rotor_angle(
    s: ScenarioData, x_q: float, how: str, q_transient: tuple[float, float] | None = None
) -> ScenarioData:
    """The scenario with delta, I_d and I_q reconstructed from V, P, Q with ``x_q`` (a copy);
    ``q_transient``: (X'_q, T'_q0) held by the user, to follow the q axis's flux (round rotor)."""
    theta = _theta(s)
    current = stator_current(s)
    if q_transient is None:
        delta = theta + load_angle(s["v_t"], theta, current, x_q)
        what = f"X_q = {x_q:.4g} pu ({how}), the q axis at rest (exact for a salient-pole rotor)"
    else:
        delta = theta + dynamic_load_angle(s, x_q, *q_transient)
        what = f"X_q = {x_q:.4g} pu ({how}), X'_q = {q_transient[0]:g} pu and T'_q0 = {q_transient[1]:g} s held"
    i_d, i_q = terminal_to_dq(np.abs(current), delta, np.angle(current))
    return with_channels(
        s,
        {"theta_t": theta, "delta": delta, "i_d": i_d, "i_q": i_q},
        f"rotor angle reconstructed from V_t, P, Q with {what}",
    )


def with_channels(s: ScenarioData, channels: dict[str, Array], note: str) -> ScenarioData:
    """A copy of the scenario with ``channels`` put in (derived from the recorded ones) and a note."""
    values = np.array(s.frame.values, order="F")
    for c, x in channels.items():
        values[:, CHANNEL_INDEX[c]] = x
    return ScenarioData(
        s.name,
        s.kind,
        s.role,
        s.generator_damping,
        Frame(s.frame.t_ns, values, s.frame.period_ns),
        s.k_event,
        s.k_clear,
        [*s.notes, note],
        list(s.extra_switching),
        s.measurement_window_s,
        s.absent - set(channels),
        s.steady_start,
        s.regulator,
        s.recorded,
        s.reference_step,
        s.file_time_s,
    )


def rotor_speed(s: ScenarioData, x_q: float, q_transient: tuple[float, float] | None, f_nominal_hz: float) -> Array:
    """The rotor speed (pu) from the reconstructed rotor angle (the recorded terminal angle plus
    the load angle) by its derivative; the swing equation's low-pass takes the noise out."""
    rebuilt = with_rotor_angle(s, x_q, "held", q_transient)
    return 1.0 + np.gradient(np.unwrap(rebuilt["delta"]), s.dt) / omega_s(f_nominal_hz)


# -- steady states: X_d (and X_q) from E_fd = V_q + X_d I_d --------------------------------------
@dataclass
class SteadyTerminalPoint:
    scenario: str
    v_t: float
    p_e: float
    q_e: float
    v_f: float


@dataclass
class SteadyReactances:
    X_d: Estimate
    X_q: Estimate
    points: list[SteadyTerminalPoint]
    rms_pu: float
    problems: list[str]


def steady_terminal_points(scenarios: Sequence[ScenarioData]) -> list[SteadyTerminalPoint]:
    """Means over each loaded scenario's steady parts: before its event and its final fifth."""
    out = []
    for s in scenarios:
        if s.role != "identify" or not s.has("v_f") or at_no_load(s):
            continue
        parts = [s.pre_slice()] if s.k_event >= 10 else []
        if s.kind in ("torque_step", "voltage_step", "field_step"):
            parts.append(s.steady_slice())
        for sl in parts:
            m = {c: float(np.mean(s[c][sl])) for c in ("v_t", "p_e", "q_e", "v_f")}
            out.append(SteadyTerminalPoint(s.name, **m))
    return out


def _residuals(pts: Sequence[SteadyTerminalPoint], x_q: float) -> tuple[Array, Array]:
    """(E_fd - V_q, I_d) at each point for this X_q: X_d is their slope through the origin."""
    v = np.array([p.v_t for p in pts])
    i = np.conj(np.array([complex(p.p_e, p.q_e) for p in pts]) / v)
    d = np.angle(v + 1j * x_q * i)  # the load angle, V at angle 0
    _, v_q = terminal_to_dq(v, d, np.zeros_like(v))
    i_d, _ = terminal_to_dq(np.abs(i), d, np.angle(i))
    return np.array([p.v_f for p in pts]) - v_q, i_d


def _slope(y: Array, x: Array) -> float:
    return float(x @ y / (x @ x))


def steady_reactances(scenarios: Sequence[ScenarioData], x_q_held: float | None = None) -> SteadyReactances:
    """X_d and X_q (or X_d with X_q held) from the steady states of V_t, P, Q and E_fd.

    For a trial X_q the d-axis relation is linear in X_d (a slope through the origin), so the fit
    is one bounded search over X_q (variable projection); the standard deviations come from the
    residuals' Jacobian in (X_d, X_q), so X_d's carries what X_q's uncertainty does to it.
    """
    pts = steady_terminal_points(scenarios)
    if len(pts) < MIN_POINTS:
        raise TerminalError(
            f"X_d from the terminal quantities needs {MIN_POINTS} loaded steady states with E_fd, "
            f"got {len(pts)}; record steps at several loadings and let them settle"
        )
    problems: list[str] = []

    def sse(x_q: float) -> float:
        y, x = _residuals(pts, x_q)
        r = y - _slope(y, x) * x
        return float(r @ r)

    if x_q_held is None:
        lo, hi = (math.log(b) for b in X_Q_SEARCH)
        grid = np.linspace(lo, hi, 25)
        vals = [sse(math.exp(g)) for g in grid]
        k = int(np.argmin(vals))
        best = minimize_scalar(
            lambda g: sse(math.exp(g)),
            bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
            method="bounded",
            options={"xatol": 1e-8},
        )
        x_q = math.exp(float(best.x))
    else:
        x_q = x_q_held
    y, x = _residuals(pts, x_q)
    x_d = _slope(y, x)

    def resid(xd: float, xq: float) -> Array:
        yy, xx = _residuals(pts, xq)
        return yy - xd * xx

    r0 = resid(x_d, x_q)
    free = 2 if x_q_held is None else 1
    dof = len(pts) - free
    s2 = float(r0 @ r0) / max(dof, 1)
    h = 1e-6
    jac = np.column_stack([(resid(x_d + h, x_q) - r0) / h, (resid(x_d, x_q + h) - r0) / h])[:, :free]
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    drivers = sorted({p.scenario for p in pts})[:3]
    x_d_est = flag(Estimate(x_d, float(sd[0]) if dof > 0 else math.nan, drivers=drivers), "X_d")
    x_d_est.note = x_d_est.note or "X_d from the steady states of V_t, P, Q and E_fd (rotor angle reconstructed)"
    if x_q_held is None:
        x_q_est = flag(Estimate(x_q, float(sd[1]) if dof > 0 else math.nan, drivers=drivers), "X_q")
        if abs(x_q - X_Q_SEARCH[0]) < 1e-3 or abs(x_q - X_Q_SEARCH[1]) < 1e-3:
            x_q_est.at_bound = True
            x_q_est.disqualify(
                f"X_q = {x_q:.3g} pu is at the search bound {X_Q_SEARCH}: the steady states do not fix it"
            )
    else:
        x_q_est = held("X_q", x_q_held)
    return SteadyReactances(x_d_est, x_q_est, pts, math.sqrt(float(r0 @ r0) / len(pts)), problems)


# -- the q axis's transient, found by the d axis's residual ---------------------------------------
Q_RATIO_GRID = (0.75, 0.5, 0.35, 0.25)  # X'_q / X_q tried (1: the static reconstruction)
T_Q0_GRID = (0.05, 0.1, 0.2, 0.4, 0.8)  # s


@dataclass
class QAxisSearch:
    """The q-axis transient (X'_q, T'_q0; None: at rest) that makes the reconstructed d axis most
    consistent."""

    q_transient: tuple[float, float] | None
    sse: float
    sse_at_rest: float
    evaluations: int


def q_axis_search(scenarios: Sequence[ScenarioData], x_q: float, x_d: float, prefilter_hz: float | None) -> QAxisSearch:
    """(X'_q, T'_q0) for the reconstruction, chosen by the d axis's state-consistency residual.

    A round-rotor machine's q-axis flux lags I_q through a disturbance, and the static
    reconstruction then puts the rotor off by (X_q - X'_q) Delta I_q / E_Q: on a round-rotor set
    (X'_q = 0.34 X_q, T'_q0 = 0.14 s) it biased X'_d +6 %. The d axis's residual is smallest
    where the reconstruction is right (there, noiseless, X'_d came back to 1e-5; X'_q and T'_q0
    to 1 %), so a grid and a simplex over (log X'_q/X_q, log T'_q0) find the q axis the data
    need; at rest (a salient pole) stays when nothing beats it. The values steer the
    reconstruction only: they are not published.
    """
    from scipy.optimize import minimize

    from phid_ros.ident import stage3

    count = [0]

    def sse(q: tuple[float, float] | None) -> float:
        count[0] += 1
        rec = [with_rotor_angle(s, x_q, "search", q) for s in scenarios]
        data = stage3.prepare(rec, prefilter_hz)
        return stage3._profile(data, True, x_d, stage3.T_D0_BOUNDS, [0]).sse

    at_rest = sse(None)
    best, best_q = at_rest, None
    for r in Q_RATIO_GRID:
        for t in T_Q0_GRID:
            v = sse((r * x_q, t))
            if v < best:
                best, best_q = v, (r * x_q, t)
    if best_q is None:
        return QAxisSearch(None, best, at_rest, count[0])

    def unpack(z: Array) -> tuple[float, float] | None:
        ratio = math.exp(min(float(z[0]), 0.0))
        return None if ratio > 0.995 else (ratio * x_q, math.exp(float(np.clip(z[1], math.log(0.01), math.log(5.0)))))

    res = minimize(
        lambda z: sse(unpack(z)),
        [math.log(best_q[0] / x_q), math.log(best_q[1])],
        method="Nelder-Mead",
        options={"xatol": 0.01, "fatol": 1e-9 * best, "maxfev": 30},
    )
    if res.fun < best:
        best, best_q = float(res.fun), unpack(res.x)
    return QAxisSearch(best_q, best, at_rest, count[0])
