"""The play-in's integration compiled (numba): the plant's equations per column, in one loop.

Why: a diagnosis integrates the plant millions of steps on a few dozen columns, where numpy
spends its time on the call overhead of some forty small array operations per right-hand
side, not on arithmetic (a run of one model cost nearly what a run of a dozen did). Compiled,
the same steps take a few percent of that time.

What: the generator model (5)-(13) of :class:`~phid_ros.sim.plant.Plant` with the stator
resistance and the registered effects that declare their terms (``PlantEffect.kernel_terms``),
driven by the measured terminal phasor (no network: the play-in's zero-impedance source).
The numpy plant (``Plant._rhs`` with the effects' hooks) stays the reference: a test runs
both on every effect combination and holds them equal to rounding, and :func:`integrate`
returns None, so the caller falls back to numpy, when numba is not installed, when
``PHID_NO_JIT`` is set, or when an effect has no compiled terms.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

# rows of the per-column coefficient matrix the kernel reads
ROWS = (
    "inv_2h",
    "xd_diff",
    "xq_diff",
    "inv_td0",
    "inv_tq0",
    "x_d_prime",
    "x_q_prime",
    "r_a",
    "damping",
    "s10",  # magnetic saturation: S(1.0), and the exponent of S(E) = S(1.0) exp(b (E - 1))
    "sat_b",
    "x_dpp",  # subtransient dynamics
    "x_qpp",
    "t_d0pp",
    "t_q0pp",
    "h_t",  # shaft torsion: turbine and generator inertia, stiffness, shaft damping
    "h_g",
    "k_shaft",
    "d_shaft",
)
ROW = {name: i for i, name in enumerate(ROWS)}
# the same indices as constants, which the compiled code reads as literals
INV_2H, XD_DIFF, XQ_DIFF, INV_TD0, INV_TQ0, XDP, XQP, R_A, DAMPING = range(9)
S10, SAT_B, X_DPP, X_QPP, T_D0PP, T_Q0PP, H_T, H_G, K_SHAFT, D_SHAFT = range(9, 19)

try:
    from numba import njit

    _jit: Any = njit(cache=True, nogil=True)  # cache: compiled once per machine, not per process
except ImportError:  # the numpy path runs instead
    njit = None
    _jit = None


def available() -> bool:
    """numba importable and not switched off (``PHID_NO_JIT=1``)."""
    return njit is not None and not os.environ.get("PHID_NO_JIT")


def integrate(
    plant: Any,
    x0: Array,
    n_steps: int,
    h: float,
    staged: tuple[Array, Array, Array, Array],
    source: NDArray[np.int64],
    damping: Array,
) -> Array | None:
    """RK4 of ``plant`` from ``x0`` (n_states, cols): states (n_steps + 1, n_states, cols), or None.

    ``staged`` = (P_m, V_f, V_t, theta_t) at every half step (rows 2k + j at t_k + j h/2),
    as :func:`phid_ros.numerics.rk4` reads them; ``source[i, c]`` is the column of input ``i``
    that model column ``c`` reads (models of one scenario share its measured inputs unless an
    effect re-times them per model). None when the compiled path cannot run.
    """
    if not available():
        return None
    terms = _terms(plant, x0.shape[1], damping)
    if terms is None:
        return None
    coef, flags = terms
    p_m, v_f, v_t, theta = (np.ascontiguousarray(a, dtype=np.float64) for a in staged)
    return _rk4_columns(
        np.ascontiguousarray(x0, dtype=np.float64),
        p_m,
        v_f,
        v_t,
        theta,
        np.ascontiguousarray(source, dtype=np.int64),
        coef,
        flags[0],
        flags[1],
        flags[2],
        float(plant.ws),
        int(n_steps),
        float(h),
    )


def _terms(plant: Any, cols: int, damping: Array) -> tuple[Array, tuple[int, int, int]] | None:
    """The coefficient matrix (len(ROWS), cols) and the flags, or None for an unsupported plant."""
    p = plant.params
    coef = np.zeros((len(ROWS), cols))

    def put(name: str, value: Any) -> None:
        coef[ROW[name]] = np.broadcast_to(np.asarray(value, dtype=np.float64), (cols,))

    put("inv_2h", plant.inv_2h)
    put("xd_diff", plant.xd_diff)
    put("xq_diff", plant.xq_diff)
    put("inv_td0", plant.inv_td0)
    put("inv_tq0", plant.inv_tq0)
    put("x_d_prime", p.X_d_prime)
    put("x_q_prime", p.X_q_prime)
    put("r_a", plant.r_a)
    put("damping", damping)
    flags = {"saturation": 0, "subtransient": -1, "torsion": -1}
    for effect, sl in zip(plant.effects, plant.slots):
        found = effect.kernel_terms(plant)
        if found is None:
            return None
        for name, value in found.items():
            if name in flags:
                flags[name] = 1 if name == "saturation" else sl.start
            else:
                put(name, value)
    return coef, (flags["saturation"], flags["subtransient"], flags["torsion"])


def _maybe_jit(f: Any) -> Any:
    return _jit(f) if _jit is not None else f


@_maybe_jit
def _rhs_column(
    x: Array,
    out: Array,
    c: int,
    pm: float,
    vf: float,
    vt: float,
    th: float,
    coef: Array,
    sat: int,
    sub_at: int,
    tor_at: int,
    ws: float,
) -> None:
    """dx/dt of one column: the same operations, in the same order, as ``Plant._rhs``."""
    delta, omega, e_q, e_d = x[0], x[1], x[2], x[3]
    if sub_at >= 0:  # subtransient dynamics provide the EMF behind X''_d, X''_q
        eq_i, ed_i, xd_i, xq_i = x[sub_at], x[sub_at + 1], coef[X_DPP, c], coef[X_QPP, c]
    else:
        eq_i, ed_i, xd_i, xq_i = e_q, e_d, coef[XDP, c], coef[XQP, c]
    ang = delta - th
    vth_d = vt * np.sin(ang)
    vth_q = vt * np.cos(ang)
    r = 0.0 + coef[R_A, c]
    a12 = xq_i + 0.0
    a21 = xd_i + 0.0
    det = -(r * r + a12 * a21)
    b1 = vth_d - ed_i
    b2 = eq_i - vth_q
    i_d = (b1 * r - a12 * b2) / det
    i_q = (-r * b2 - a21 * b1) / det
    p_airgap = ed_i * i_d + eq_i * i_q + (xq_i - xd_i) * i_d * i_q
    slip = omega - 1.0
    damping = coef[DAMPING, c]
    d_omega = (pm - p_airgap - damping * slip) * coef[INV_2H, c]
    loss = 0.0
    if sat:
        loss = 0.0 + coef[S10, c] * np.exp(coef[SAT_B, c] * (e_q - 1.0)) * e_q
    out[0] = ws * slip
    out[2] = (vf - e_q - coef[XD_DIFF, c] * i_d - loss) * coef[INV_TD0, c]
    out[3] = (coef[XQ_DIFF, c] * i_q - e_d) * coef[INV_TQ0, c]
    if tor_at >= 0:
        h_t, h_g, k = coef[H_T, c], coef[H_G, c], coef[K_SHAFT, c]
        torque = k * (x[tor_at] - delta) + coef[D_SHAFT, c] * (x[tor_at + 1] - omega)
        d_omega = (torque - p_airgap - damping * (omega - 1.0)) / (2 * h_g)
        out[tor_at] = ws * (x[tor_at + 1] - 1.0)
        out[tor_at + 1] = (pm - torque) / (2 * h_t)
    if sub_at >= 0:
        out[sub_at] = (e_q - x[sub_at] - (coef[XDP, c] - coef[X_DPP, c]) * i_d) / coef[T_D0PP, c]
        out[sub_at + 1] = (e_d - x[sub_at + 1] + (coef[XQP, c] - coef[X_QPP, c]) * i_q) / coef[T_Q0PP, c]
    out[1] = d_omega


@_maybe_jit
def _rk4_columns(
    x0: Array,
    p_m: Array,
    v_f: Array,
    v_t: Array,
    theta: Array,
    source: NDArray[np.int64],
    coef: Array,
    sat: int,
    sub_at: int,
    tor_at: int,
    ws: float,
    n_steps: int,
    h: float,
) -> Array:
    n_states, cols = x0.shape
    states = np.empty((n_steps + 1, n_states, cols))
    states[0] = x0
    h2, h6 = 0.5 * h, h / 6.0
    x = np.empty(n_states)
    xs = np.empty(n_states)
    k1, k2, k3, k4 = np.empty(n_states), np.empty(n_states), np.empty(n_states), np.empty(n_states)
    for c in range(cols):
        pm, vf, vt, th = source[0, c], source[1, c], source[2, c], source[3, c]
        for i in range(n_states):
            x[i] = x0[i, c]
        for k in range(n_steps):
            a, b, e = 2 * k, 2 * k + 1, 2 * k + 2
            _rhs_column(x, k1, c, p_m[a, pm], v_f[a, vf], v_t[a, vt], theta[a, th], coef, sat, sub_at, tor_at, ws)
            for i in range(n_states):
                xs[i] = x[i] + h2 * k1[i]
            _rhs_column(xs, k2, c, p_m[b, pm], v_f[b, vf], v_t[b, vt], theta[b, th], coef, sat, sub_at, tor_at, ws)
            for i in range(n_states):
                xs[i] = x[i] + h2 * k2[i]
            _rhs_column(xs, k3, c, p_m[b, pm], v_f[b, vf], v_t[b, vt], theta[b, th], coef, sat, sub_at, tor_at, ws)
            for i in range(n_states):
                xs[i] = x[i] + h * k3[i]
            _rhs_column(xs, k4, c, p_m[e, pm], v_f[e, vf], v_t[e, vt], theta[e, th], coef, sat, sub_at, tor_at, ws)
            for i in range(n_states):
                x[i] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
                states[k + 1, i, c] = x[i]
    return states
