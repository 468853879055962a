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
from concurrent.futures import ThreadPoolExecutor
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
    "sat_curve",  # magnetic saturation: 1 exponential, 0 quadratic; the curve's two constants;
    "sat_c1",  # the q-axis share (X_q - X_l)/(X_d - X_l) of GENROU's form
    "sat_c2",
    "sat_q",
    "x_dpp",  # subtransient dynamics (GENROU's dampers): reactances, time constants, X_l,
    "x_qpp",  # the flux shares g_d, g_q and the dampers' load on the transient windings
    "t_d0pp",
    "t_q0pp",
    "x_l",
    "g_d",
    "g_q",
    "load_d",
    "load_q",
    "h_t",  # shaft torsion: turbine and generator inertia, stiffness, shaft damping
    "h_g",
    "k_shaft",
    "d_shaft",
)
ROW = {name: i for i, name in enumerate(ROWS)}
# the same indices as constants, which the compiled code reads as literals
INV_2H, XD_DIFF, XQ_DIFF, INV_TD0, INV_TQ0, XDP, XQP, R_A, DAMPING = range(9)
SAT_CURVE, SAT_C1, SAT_C2, SAT_Q = range(9, 13)
X_DPP, X_QPP, T_D0PP, T_Q0PP, X_L, G_D, G_Q, LOAD_D, LOAD_Q = range(13, 22)
H_T, H_G, K_SHAFT, D_SHAFT = range(22, 26)
SATURATION_FORMS = {"gensal": 1, "genrou": 2}  # the kernel's `sat` flag; 0: none

try:
    from numba import njit

    _jit: Any = njit(cache=True, nogil=True, error_model="numpy")  # cache: compiled once per machine, not per process
except ImportError:  # the numpy path runs instead
    njit = None
    _jit = None


def available() -> bool:
    """numba importable and not switched off (``PHID_NO_JIT=1``)."""
    return njit is not None and not os.environ.get("PHID_NO_JIT")


OUTPUTS = ("delta", "omega", "i_d", "i_q", "p_e", "q_e")  # rows of what :func:`integrate` returns


def integrate(
    plant: Any,
    x0: Array,
    n_steps: int,
    h: float,
    staged: tuple[Array, Array, Array, Array],
    source: NDArray[np.int64],
    damping: Array,
    threads: int = 1,
) -> Array | None:
    """RK4 of ``plant`` from ``x0`` (n_states, cols): its OUTPUTS (6, n_steps + 1, cols), or None.

    ``staged`` = (P_m, V_f, V_t, theta_t) at every half step (rows 2k + j at t_k + j h/2),
    as :func:`phid_ros.numerics.rk4` reads them; ``source[i, c]`` is the column of input ``i``
    that model column ``c`` reads (models of one scenario share its measured inputs unless an
    effect re-times them per model). The outputs at step k are the plant's at its state x_k and
    the inputs of row 2k (the play-in's terminal is the source: V = V_th), computed where the
    step computes them anyway, so no trajectory of states is stored. None when the compiled
    path cannot run. ``threads``: the columns split over this many threads (the compiled loop
    holds no GIL, and each column's arithmetic is the same wherever it runs).
    """
    if not available():
        return None
    terms = _terms(plant, x0.shape[1], damping)
    if terms is None:
        return None
    coef, flags = terms
    p_m, v_f, v_t, theta = (np.ascontiguousarray(a, dtype=np.float64) for a in staged)
    cols = x0.shape[1]

    def run(a: int, b: int) -> Array:
        return _rk4_outputs(
            np.ascontiguousarray(x0[:, a:b], dtype=np.float64),
            p_m,
            v_f,
            v_t,
            theta,
            np.ascontiguousarray(source[:, a:b], dtype=np.int64),
            np.ascontiguousarray(coef[:, a:b]),
            flags[0],
            flags[1],
            flags[2],
            float(plant.ws),
            int(n_steps),
            float(h),
        )

    parts = min(threads, cols // 2)
    if parts <= 1:
        return run(0, cols)
    edges = np.linspace(0, cols, parts + 1).astype(int)
    with ThreadPoolExecutor(parts, "phid-kernel") as pool:
        return np.concatenate(list(pool.map(run, edges[:-1], edges[1:])), axis=2)


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
                flags[name] = int(value) if name == "saturation" else sl.start
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
) -> tuple[float, float, float, float]:
    """dx/dt of one column: the same operations, in the same order, as ``Plant._rhs``.

    Returns the stator solution it used, (I_d, I_q, V_d, V_q), for the outputs."""
    delta, omega, e_q, e_d = x[0], x[1], x[2], x[3]
    if sub_at >= 0:  # GENROU's dampers: the EMF behind X''_d, X''_q is the air-gap flux psi''
        g_d, g_q = coef[G_D, c], coef[G_Q, c]
        eq_i = g_d * e_q + (1.0 - g_d) * x[sub_at]
        ed_i = g_q * e_d + (1.0 - g_q) * x[sub_at + 1]
        xd_i, xq_i = coef[X_DPP, c], coef[X_QPP, c]
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
    loss_d = 0.0
    loss_q = 0.0
    if sat > 0:
        psi = e_q if sat == 1 else np.sqrt(eq_i * eq_i + ed_i * ed_i)
        c1, c2 = coef[SAT_C1, c], coef[SAT_C2, c]
        if coef[SAT_CURVE, c] > 0.5:
            s = c1 * psi**c2
        else:
            over = max(psi - c1, 0.0)
            s = c2 * over * over / psi
        if sat == 1:
            loss_d = loss_d + s * e_q
        else:
            loss_d = loss_d + s * eq_i
            loss_q = loss_q + s * ed_i * coef[SAT_Q, c]
    if sub_at >= 0:
        x_l = coef[X_L, c]
        drive_d = e_q - x[sub_at] - (coef[XDP, c] - x_l) * i_d
        drive_q = e_d - x[sub_at + 1] + (coef[XQP, c] - x_l) * i_q
        loss_d = loss_d + coef[LOAD_D, c] * drive_d
        loss_q = loss_q + coef[LOAD_Q, c] * drive_q
        out[sub_at] = drive_d / coef[T_D0PP, c]
        out[sub_at + 1] = drive_q / coef[T_Q0PP, c]
    out[0] = ws * slip
    out[2] = (vf - e_q - coef[XD_DIFF, c] * i_d - loss_d) * coef[INV_TD0, c]
    out[3] = (coef[XQ_DIFF, c] * i_q - e_d - loss_q) * coef[INV_TQ0, c]
    if tor_at >= 0:
        h_t, h_g, k = coef[H_T, c], coef[H_G, c], coef[K_SHAFT, c]
        torque = k * (x[tor_at] - delta) + coef[D_SHAFT, c] * (x[tor_at + 1] - omega)
        d_omega = (torque - p_airgap - damping * (omega - 1.0)) / (2 * h_g)
        out[tor_at] = ws * (x[tor_at + 1] - 1.0)
        out[tor_at + 1] = (pm - torque) / (2 * h_t)
    out[1] = d_omega
    return i_d, i_q, vth_d, vth_q


@_maybe_jit
def _rk4_outputs(
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
    # Steps outer, columns inner: every write of a step is contiguous over the columns. Written
    # per column (steps inner) the outputs' rows were a cache line apart, and the play-in spent
    # most of its time on those misses. Each column's arithmetic is the same in either order.
    n_states, cols = x0.shape
    out = np.empty((6, n_steps + 1, cols))
    xall = x0.copy()
    h2, h6 = 0.5 * h, h / 6.0
    x = np.empty(n_states)
    xs = np.empty(n_states)
    k1, k2, k3, k4 = np.empty(n_states), np.empty(n_states), np.empty(n_states), np.empty(n_states)
    for k in range(n_steps + 1):
        a, b, e = 2 * k, 2 * k + 1, 2 * k + 2
        for c in range(cols):
            pm, vf, vt, th = source[0, c], source[1, c], source[2, c], source[3, c]
            for i in range(n_states):
                x[i] = xall[i, c]
            i_d, i_q, v_d, v_q = _rhs_column(
                x, k1, c, p_m[a, pm], v_f[a, vf], v_t[a, vt], theta[a, th], coef, sat, sub_at, tor_at, ws
            )
            out[0, k, c] = x[0]
            out[1, k, c] = x[1]
            out[2, k, c] = i_d
            out[3, k, c] = i_q
            out[4, k, c] = v_d * i_d + v_q * i_q  # electrical_power: P_e (13) and Q_e
            out[5, k, c] = v_q * i_d - v_d * i_q
            if k == n_steps:
                continue
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
                xall[i, c] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    return out
