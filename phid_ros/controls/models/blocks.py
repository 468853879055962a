"""The blocks the control models are built from, each a plain function of an input's samples.

Tustin-free: each first-order lag is :func:`phid_ros.numerics.first_order_response`, exact for
inputs linear between samples: ``lag(T)`` = 1/(1 + sT); ``lead_lag(T_lead, T_lag)`` =
(1 + sT_lead)/(1 + sT_lag) = T_lead/T_lag + (1 - T_lead/T_lag) lag(T_lag). A model with a
feedback loop (a rate feedback around the regulator, the droop around a hydro governor's PI) is
its closed loop's transfer function, :func:`transfer`, discretised with the same first-order
hold. The limited blocks (a non-windup lag, a non-windup lead-lag) step sample by sample,
compiled on their first call.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from phid_ros.jit import jit_on_first_call
from phid_ros.numerics import first_order_coefficients, first_order_response

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ControlInputs:
    """One scenario's deviations from its pre-event steady state, on its sample grid."""

    dt: float
    v_t: Array  # terminal voltage deviation, pu
    speed: Array  # rotor speed deviation, pu
    # the unit step at the scenario's reference change (zeros if none), or the recorded set-point's
    # deviation, played with a reference of 1 (:func:`phid_ros.controls.cases.recorded_set_point`)
    reference_step: Array
    p_m0: float = float("nan")  # mechanical power before the event, pu (a hydro turbine's operating point)
    p_e: Array | None = None  # electrical power deviation, pu (a stabiliser's input), where recorded
    v_s: Array | None = None  # a stabiliser's output deviation, pu, where recorded (joins the regulator's error)


def regulator_error(x: ControlInputs, reference: float, sensed: Array) -> Array:
    """An exciter's error at its summing point, IEEE 421.5's V_REF - V_C + V_S: the reference step,
    the sensed terminal voltage and, where recorded, the stabiliser's output."""
    e = reference * x.reference_step - sensed
    return e if x.v_s is None else e + x.v_s


def lag(u: Array, tau: float, dt: float) -> Array:
    """1/(1 + s tau) from rest; a vanishing tau is a wire."""
    return u if tau <= 1e-6 else first_order_response(u, tau, dt)


def transfer(u: Array, num: Sequence[float] | np.ndarray, den: Sequence[float] | np.ndarray, dt: float) -> Array:
    """num(s)/den(s) (coefficients from the highest power) from rest, for inputs linear between
    samples (first-order hold, as :func:`lag`)."""
    from scipy.signal import lfilter

    direct, modes = _discrete_modes(tuple(map(float, num)), tuple(map(float, den)), float(dt))
    y = np.asarray(direct * u, dtype=np.complex128)
    for lam_i, g_in, g_out in modes:
        y += g_out * lfilter([0.0, g_in], [1.0, -lam_i], u)
    return np.ascontiguousarray(y.real)


@lru_cache(maxsize=256)
def _discrete_modes(
    num: tuple[float, ...], den: tuple[float, ...], dt: float
) -> tuple[float, tuple[tuple[complex, complex, complex], ...]]:
    """The first-order-hold discretisation of num/den, mode by mode: the direct gain and each
    mode's (pole, input gain, output gain). Cached: a fit's scenarios share one step."""
    from scipy.signal import cont2discrete, tf2ss

    # mode by mode: a direct-form polynomial of degree four in z with poles near 1 (time
    # constants of seconds at 1 ms) rounds its response into noise a finite-difference Jacobian
    # takes for slopes (1e-5 of the output; a hydro governor's fit stalled at its start), and so
    # did second-order sections through the discrete zeros; each mode is a first-order recursion
    ad, bd, cd, dd, _ = cont2discrete(tf2ss(np.asarray(num), np.asarray(den)), dt, method="foh")
    lam, vec = np.linalg.eig(ad)
    gain_in = np.linalg.solve(vec, bd[:, 0])
    gain_out = cd[0] @ vec
    return float(dd[0, 0]), tuple((complex(a), complex(b), complex(c)) for a, b, c in zip(lam, gain_in, gain_out))


def first_order(t: float) -> NDArray[np.float64]:
    """1 + sT as a polynomial in s."""
    return np.array([t, 1.0])


def nonwindup_lag(u: Array, tau: float, dt: float, lo: Array, hi: Array, x0: float) -> Array:
    """1/(1 + s tau) from ``x0`` with its state held within [lo, hi] (IEEE 421.5's non-windup
    limit: the output leaves a limit as soon as the input turns back)."""
    if tau <= 1e-6:
        return np.clip(u, lo, hi)
    a, b0, b1 = first_order_coefficients(tau, dt)
    f64 = np.float64
    return _nonwindup_lag_loop(np.asarray(u, f64), a, b0, b1, np.asarray(lo, f64), np.asarray(hi, f64), float(x0))


def _nonwindup_lag_steps(u: Array, a: float, b0: float, b1: float, lo: Array, hi: Array, x0: float) -> Array:
    y = np.empty(len(u))
    x = x0
    prev = u[0] if len(u) else 0.0
    for k in range(len(u)):
        x = min(max(a * x + b0 * prev + b1 * u[k], lo[k]), hi[k])
        y[k] = x
        prev = u[k]
    return y


# compiled where numba is (a limited exciter's fit plays this loop at every evaluation of every case)
_nonwindup_lag_loop = jit_on_first_call(_nonwindup_lag_steps)


def nonwindup_lead_lag(u: Array, t_lead: float, t_lag: float, dt: float, lo: float, hi: float, x0: float) -> Array:
    """(1 + s t_lead)/(1 + s t_lag) from rest at ``x0`` with a non-windup limit on its output
    (IEEE 421.5): at a limit the output sits on it and the lag's state does not move further
    beyond it, so the output leaves the limit as soon as the input allows. Setting the state so
    that the output sits exactly on the limit instead drove it far the other way behind a large
    lead (T_C/T_B 0.077 under a gain of 505: a +10 % reference step sent E_fd to the floor)."""
    if t_lag <= 1e-6:
        return np.clip(u, lo, hi)
    a, b0, b1 = first_order_coefficients(t_lag, dt)
    return _nonwindup_lead_lag_loop(
        np.asarray(u, np.float64), t_lead / t_lag, a, b0, b1, float(lo), float(hi), float(x0)
    )


def _nonwindup_lead_lag_steps(
    u: Array, r: float, a: float, b0: float, b1: float, lo: float, hi: float, x0: float
) -> Array:
    y = np.empty(len(u))
    x = x0
    prev = u[0] if len(u) else 0.0
    for k in range(len(u)):
        uk = u[k]
        moved = a * x + b0 * prev + b1 * uk
        out = r * uk + (1.0 - r) * moved
        if out > hi:
            out = hi
            moved = min(moved, x) if 1.0 - r > 0 else max(moved, x)
        elif out < lo:
            out = lo
            moved = max(moved, x) if 1.0 - r > 0 else min(moved, x)
        x = moved
        y[k] = out
        prev = uk
    return y


# compiled where numba is: ST5B's fit plays this loop at every evaluation of every case (a
# commissioning day's exciter search spent 87 of its 290 s in it as Python)
_nonwindup_lead_lag_loop = jit_on_first_call(_nonwindup_lead_lag_steps)


def lead_lag(u: Array, t_lead: float, t_lag: float, dt: float) -> Array:
    """(1 + s t_lead)/(1 + s t_lag) from rest."""
    if t_lag <= 1e-6:
        return u
    r = t_lead / t_lag
    return r * u + (1.0 - r) * first_order_response(u, t_lag, dt)


def _lead_lag_steps(t_lead: float, t_lag: float, dt: float) -> tuple[float, float, float, float]:
    """(r, a, b0, b1): (1 + s t_lead)/(1 + s t_lag) as r u + (1 - r) x, the lag's state x stepped
    by :func:`~phid_ros.numerics.first_order_coefficients`; a vanishing lag is a wire."""
    if t_lag <= 1e-6:
        return 1.0, 0.0, 0.0, 1.0
    return (t_lead / t_lag, *first_order_coefficients(t_lag, dt))


def lead_lags_in_order(
    values: Mapping[str, float], pairs: Sequence[tuple[str, str]] = (("T1", "T2"), ("T3", "T4"))
) -> dict[str, float]:
    """A stabiliser's lead-lags (T_1, T_2), (T_3, T_4), ... in one order, so a fit has one answer:
    (1 + sT_1)(1 + sT_3)/((1 + sT_2)(1 + sT_4)) is the same whichever lead a lag is paired with, so
    the shorter lead goes with the shorter lag, first (a lead the fit finds absent is T_1)."""
    leads = sorted(values[lead] for lead, _ in pairs)
    lags = sorted(values[lag_] for _, lag_ in pairs)
    return {n: v for (lead, lag_), a, b in zip(pairs, leads, lags, strict=True) for n, v in ((lead, a), (lag_, b))}


def washout(u: Array, tau: float, dt: float) -> Array:
    """s tau/(1 + s tau) from rest; a vanishing tau is a wire (PSS/E bypasses a washout of T = 0)."""
    return u if tau <= 1e-6 else u - lag(u, tau, dt)
