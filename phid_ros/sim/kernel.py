"""The play-in's integration compiled (numba): the plant's equations per column, in one loop.

Why: a diagnosis integrates the plant millions of steps on a few dozen columns, where numpy
spends its time on the call overhead of some forty small array operations per right-hand
side, not on arithmetic (a run of one model cost nearly what a run of a dozen did). Compiled,
the same steps take a few percent of that time.

What: the generator model (5)-(13) of :class:`~phid_ros.sim.plant.Plant` with the stator
resistance and the registered effects that declare their terms (``PlantEffect.kernel_terms``),
driven by the measured terminal phasor (no network: the play-in's zero-impedance source).
The equations are not written here: the kernel compiles ``model/equations``' and
``model/conventions``' functions and the effects' term functions as they are, and only says
in which order a column calls them.
The numpy plant (``Plant._rhs`` with the effects' hooks) stays the reference: a test runs
both on every effect combination and holds them equal to rounding, and :func:`integrate`
returns None, so the caller falls back to numpy, when numba is not installed, when
``PHID_NO_JIT`` is set, or when an effect has no compiled terms.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.jit import available, maybe_jit
from phid_ros.model import conventions, equations
from phid_ros.sim import effects

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
    "x_dpp",  # subtransient dynamics (GENROU's dampers): reactances, time constants,
    "x_qpp",  # X'_d - X_l and X'_q - X_l, the flux shares g_d, g_q and the dampers' load on
    "t_d0pp",  # the transient windings
    "t_q0pp",
    "xdp_l",
    "xqp_l",
    "g_d",
    "g_q",
    "load_d",
    "load_q",
    "inv_2h_t",  # shaft torsion: 1/2H of turbine and generator, stiffness, shaft damping
    "inv_2h_g",
    "k_shaft",
    "d_shaft",
)
ROW = {name: i for i, name in enumerate(ROWS)}
# the same indices as constants, which the compiled code reads as literals
INV_2H, XD_DIFF, XQ_DIFF, INV_TD0, INV_TQ0, XDP, XQP, R_A, DAMPING = range(9)
SAT_CURVE, SAT_C1, SAT_C2, SAT_Q = range(9, 13)
X_DPP, X_QPP, T_D0PP, T_Q0PP, XDP_L, XQP_L, G_D, G_Q, LOAD_D, LOAD_Q = range(13, 23)
INV_2H_T, INV_2H_G, K_SHAFT, D_SHAFT = range(23, 27)
SATURATION_FORMS = {"gensal": 1, "genrou": 2}  # the kernel's `sat` flag; 0: none

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
    args = _column_args(plant, x0, n_steps, h, staged, source, damping)
    if args is None:
        return None
    parts = _over_columns(lambda a, b: _rk4_outputs(*args(a, b)), x0.shape[1], threads)
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=2)


def integrate_residuals(
    plant: Any,
    x0: Array,
    n_steps: int,
    h: float,
    staged: tuple[Array, Array, Array, Array],
    source: NDArray[np.int64],
    damping: Array,
    residual: ResidualLayout,
    out: Array,
    threads: int = 1,
) -> bool:
    """:func:`integrate`, writing noise-normalised residuals into ``out`` instead of returning outputs.

    Why: a fit reads only ``(output - measurement) / sigma`` of each channel, stacked per
    scenario and channel (``ident.plant_playin.residuals``' rows, one column per model). Written
    there as the step computes each output, no (6, steps, columns) trajectory is stored and
    read again, and a column stops at its scenario's end. The same operations in the same
    order: the residuals are those of the outputs, bit for bit. False when the compiled path
    cannot run (``out`` untouched).
    """
    args = _column_args(plant, x0, n_steps, h, staged, source, damping)
    if args is None:
        return False
    lay = residual

    def run(a: int, b: int) -> None:  # each range writes its own columns of out
        _rk4_residuals(
            *args(a, b),
            lay.meas,
            np.ascontiguousarray(lay.msource[:, a:b]),
            lay.order,
            lay.sigma,
            lay.rows_at,
            lay.n_keep,
            int(lay.m),
            int(a),
            out,
        )

    _over_columns(run, x0.shape[1], threads)
    return True


@dataclass(frozen=True)
class ResidualLayout:
    """Where :func:`integrate_residuals` reads each measurement and writes each residual.

    ``meas`` (steps, k): measured channels at every step, side by side; ``msource[q, c]``: the
    column of ``meas`` that residual channel q of model column c is compared with; ``order[q]``:
    the OUTPUTS row of residual channel q; ``sigma[q]`` its noise; per scenario j its first
    row ``rows_at[j]`` and its steps ``n_keep[j]``; ``m`` models per scenario.
    """

    meas: Array
    msource: NDArray[np.int64]
    order: NDArray[np.int64]
    sigma: Array
    rows_at: NDArray[np.int64]
    n_keep: NDArray[np.int64]
    m: int


def _column_args(
    plant: Any,
    x0: Array,
    n_steps: int,
    h: float,
    staged: tuple[Array, Array, Array, Array],
    source: NDArray[np.int64],
    damping: Array,
) -> Callable[[int, int], tuple[Any, ...]] | None:
    """The compiled loops' common arguments for the model columns a:b, or None where the
    compiled path cannot run (numba absent or switched off, an effect without compiled terms)."""
    if not available():
        return None
    terms = _terms(plant, x0.shape[1], damping)
    if terms is None:
        return None
    coef, flags = terms
    p_m, v_f, v_t, theta = (np.ascontiguousarray(a, dtype=np.float64) for a in staged)

    def args(a: int, b: int) -> tuple[Any, ...]:
        return (
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

    return args


def _over_columns(run: Callable[[int, int], Any], cols: int, threads: int) -> list[Any]:
    """``run`` over column ranges, on up to ``threads`` threads (the compiled loops hold no GIL, and a
    column's arithmetic is the same wherever it runs); its results in column order."""
    parts = max(1, min(threads, cols // 2))
    if parts == 1:
        return [run(0, cols)]
    edges = np.linspace(0, cols, parts + 1).astype(int)
    with ThreadPoolExecutor(parts, "phid-kernel") as pool:
        return list(pool.map(run, edges[:-1], edges[1:]))


def _terms(plant: Any, cols: int, damping: Array) -> tuple[Array, tuple[int, int, int]] | None:
    """The coefficient matrix (len(ROWS), cols) and the flags, or None for an unsupported plant."""
    coef = np.zeros((len(ROWS), cols))

    def put(name: str, value: Any) -> None:
        coef[ROW[name]] = np.broadcast_to(np.asarray(value, dtype=np.float64), (cols,))

    for name in ("inv_2h", "xd_diff", "xq_diff", "inv_td0", "inv_tq0", "x_d_prime", "x_q_prime"):
        put(name, getattr(plant.coef, name))
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


# inlined: the step calls the column's right-hand side four times, and as a call each passed
# three arrays and a dozen scalars: 1.5x the time
_maybe_jit_inlined = partial(maybe_jit, inline=True)


# the equations, compiled as they are written (one place each)
_dq_of, _powers = (maybe_jit(getattr(conventions, n)) for n in ("dq_of", "powers"))
_rotor_angle, _swing, _field_d, _field_q, _stator, _airgap_power = (
    maybe_jit(getattr(equations, n)) for n in ("rotor_angle", "swing", "field_d", "field_q", "stator", "airgap_power")
)
_saturation_factor, _flux_magnitude, _damper_emf, _damper_drives, _shaft_torque = (
    maybe_jit(getattr(effects, n))
    for n in ("saturation_factor", "flux_magnitude", "damper_emf", "damper_drives", "shaft_torque")
)


@_maybe_jit_inlined
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
    """dx/dt of one column: ``Plant._rhs`` with the effects' hooks, in the same order.

    Returns the stator solution it used, (I_d, I_q, V_d, V_q), for the outputs."""
    delta, omega, e_q, e_d = x[0], x[1], x[2], x[3]
    if sub_at >= 0:  # GENROU's dampers: the EMF behind X''_d, X''_q is the air-gap flux psi''
        eq_i = _damper_emf(coef[G_D, c], e_q, x[sub_at])
        ed_i = _damper_emf(coef[G_Q, c], e_d, x[sub_at + 1])
        xd_i, xq_i = coef[X_DPP, c], coef[X_QPP, c]
    else:
        eq_i, ed_i, xd_i, xq_i = e_q, e_d, coef[XDP, c], coef[XQP, c]
    v_d, v_q = _dq_of(vt, delta - th)
    i_d, i_q = _stator(eq_i, ed_i, v_d, v_q, coef[R_A, c], xd_i, xq_i)
    p_airgap = _airgap_power(eq_i, ed_i, i_d, i_q, xd_i, xq_i)
    damping = coef[DAMPING, c]
    d_omega = _swing(pm, p_airgap, omega, damping, coef[INV_2H, c])
    loss_d = 0.0
    loss_q = 0.0
    if sat > 0:
        s = _saturation_factor(
            coef[SAT_CURVE, c] > 0.5, coef[SAT_C1, c], coef[SAT_C2, c], e_q if sat == 1 else _flux_magnitude(eq_i, ed_i)
        )
        if sat == 1:
            loss_d = loss_d + s * e_q
        else:
            loss_d = loss_d + s * eq_i
            loss_q = loss_q + s * ed_i * coef[SAT_Q, c]
    if sub_at >= 0:
        drive_d, drive_q = _damper_drives(e_q, e_d, x[sub_at], x[sub_at + 1], i_d, i_q, coef[XDP_L, c], coef[XQP_L, c])
        loss_d = loss_d + coef[LOAD_D, c] * drive_d
        loss_q = loss_q + coef[LOAD_Q, c] * drive_q
        out[sub_at] = drive_d / coef[T_D0PP, c]
        out[sub_at + 1] = drive_q / coef[T_Q0PP, c]
    out[0] = _rotor_angle(omega, ws)
    out[2] = _field_d(vf, e_q, i_d, coef[XD_DIFF, c], loss_d, coef[INV_TD0, c])
    out[3] = _field_q(e_d, i_q, coef[XQ_DIFF, c], loss_q, coef[INV_TQ0, c])
    if tor_at >= 0:
        torque = _shaft_torque(coef[K_SHAFT, c], coef[D_SHAFT, c], x[tor_at], delta, x[tor_at + 1], omega)
        d_omega = _swing(torque, p_airgap, omega, damping, coef[INV_2H_G, c])
        out[tor_at] = _rotor_angle(x[tor_at + 1], ws)
        out[tor_at + 1] = _swing(pm, torque, x[tor_at + 1], 0.0, coef[INV_2H_T, c])
    out[1] = d_omega
    return i_d, i_q, v_d, v_q


def _sources_digest() -> str:
    """The text of the files whose equations the step compiles (see :func:`_compiled_step`)."""
    digest = hashlib.sha256()
    for module in (conventions, equations, effects):
        digest.update(Path(str(module.__file__)).read_bytes())
    return digest.hexdigest()


@_maybe_jit_inlined
def _column_step(
    xall: Array,
    c: int,
    k: int,
    last: bool,
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
    h: float,
    work: Array,
    res: Array,
) -> None:
    """One RK4 step of column ``c`` from step ``k``: its OUTPUTS at x_k into ``res``, x_{k+1} into
    ``xall`` (not after the ``last`` step). ``work`` holds six state vectors (x, a stage, k1-k4)."""
    n_states = xall.shape[0]
    x, xs, k1, k2, k3, k4 = work[0], work[1], work[2], work[3], work[4], work[5]
    a, b, e = 2 * k, 2 * k + 1, 2 * k + 2
    pm, vf, vt, th = source[0, c], source[1, c], source[2, c], source[3, c]
    for i in range(n_states):
        x[i] = xall[i, c]
    i_d, i_q, v_d, v_q = _rhs_column(
        x, k1, c, p_m[a, pm], v_f[a, vf], v_t[a, vt], theta[a, th], coef, sat, sub_at, tor_at, ws
    )
    res[0] = x[0]
    res[1] = x[1]
    res[2] = i_d
    res[3] = i_q
    res[4], res[5] = _powers(v_d, v_q, i_d, i_q)  # P_e (13) and Q_e
    if last:
        return
    h2, h6 = 0.5 * h, h / 6.0
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


def _compiled_step(sources: str) -> Any:
    """The compiled RK4 play-in, keyed in numba's cache to ``sources`` as well as to this file.

    Why: the step compiles equations written in other files, and numba's cache looks only at
    the file of the function it caches; an edited equation would be served from the old code.
    A closure's variables are part of numba's cache key, so the step closes over the digest
    of those files' text.
    """

    @maybe_jit
    def rk4_outputs(
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
        _ = sources  # the key of the compiled code in numba's cache (see _compiled_step)
        # Steps outer, columns inner: every write of a step is contiguous over the columns. Written
        # per column (steps inner) the outputs' rows were a cache line apart, and the play-in spent
        # most of its time on those misses. Each column's arithmetic is the same in either order.
        n_states, cols = x0.shape
        out = np.empty((6, n_steps + 1, cols))
        xall = x0.copy()
        work = np.empty((6, n_states))
        res = np.empty(6)
        for k in range(n_steps + 1):
            for c in range(cols):
                _column_step(
                    xall, c, k, k == n_steps, p_m, v_f, v_t, theta, source, coef, sat, sub_at, tor_at, ws, h, work, res
                )
                for q in range(6):
                    out[q, k, c] = res[q]
        return out

    @maybe_jit
    def rk4_residuals(
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
        meas: Array,
        msource: NDArray[np.int64],
        order: NDArray[np.int64],
        sigma: Array,
        rows_at: NDArray[np.int64],
        n_keep: NDArray[np.int64],
        m: int,
        c0: int,
        out: Array,
    ) -> None:
        """rk4_outputs, with each output's noise-normalised residual written where the fit reads it.

        Column ``c`` (``c0 + c`` overall) is model ``(c0 + c) % m`` of scenario ``j = (c0 + c) // m``;
        its residual of channel ``order[q]`` at step k goes to row ``rows_at[j] + q n_keep[j] + k``
        of ``out`` (``plant_playin.residuals``' layout), for k below ``n_keep[j]``, where the column stops.
        """
        _ = sources
        n_states, cols = x0.shape
        xall = x0.copy()
        work = np.empty((6, n_states))
        res = np.empty(6)
        for k in range(n_steps + 1):
            for c in range(cols):
                j = (c0 + c) // m
                n = n_keep[j]
                if k >= n:
                    continue  # past this scenario's end: no output of it is read, so no step taken
                _column_step(
                    xall, c, k, k == n - 1, p_m, v_f, v_t, theta, source, coef, sat, sub_at, tor_at, ws, h, work, res
                )
                i = (c0 + c) % m
                row = rows_at[j] + k
                for q in range(6):
                    out[row + q * n, i] = (res[order[q]] - meas[k, msource[q, c]]) / sigma[q]

    return rk4_outputs, rk4_residuals


_rk4_outputs, _rk4_residuals = _compiled_step(_sources_digest())


# rows of the paper model's coefficient matrix (the validation play-in: no effects, no resistance)
PAPER_ROWS = ("inv_2h", "d", "xd_diff", "xq_diff", "inv_td0", "inv_tq0", "x_d_prime", "x_q_prime")
P_INV_2H, P_D, P_XD_DIFF, P_XQ_DIFF, P_INV_TD0, P_INV_TQ0, P_XDP, P_XQP = range(8)


def paper_rk4(x0: Array, staged: tuple[Array, Array, Array, Array], coef: Any, n_steps: int, h: float) -> Array | None:
    """The validation play-in's RK4 of (5)-(13) as written in the paper, compiled: states
    (n_steps + 1, 4, cols), or None when numba is not there (or ``PHID_NO_JIT``).

    The same steps as :func:`phid_ros.numerics.rk4` on ``validation.play_in``'s right-hand side:
    ``staged`` = (V_t, theta_t, P_m, V_f) at every half step, ``coef`` a
    :class:`~phid_ros.model.equations.Coefficients` with one entry per column. Why compiled:
    numpy spent 17 us of call overhead per right-hand side on a handful of columns, four times
    a step, and a recalibration validates every run (60 % of a replay's identification time).
    """
    if not available():
        return None
    cols = x0.shape[1]
    rows = np.array([np.broadcast_to(np.asarray(getattr(coef, n), np.float64), (cols,)) for n in PAPER_ROWS])
    v_t, theta, p_m, v_f = (np.ascontiguousarray(a, dtype=np.float64) for a in staged)
    x = np.ascontiguousarray(x0, dtype=np.float64)
    return _paper_rk4(x, v_t, theta, p_m, v_f, rows, float(coef.w_s), int(n_steps), float(h))


@maybe_jit
def _paper_rhs_column(
    x: Array, out: Array, c: int, vt: float, th: float, pm: float, vf: float, coef: Array, ws: float
) -> None:
    """dx/dt of one column: ``validation.play_in``'s right-hand side, the same operations in the same order."""
    v_d, v_q = _dq_of(vt, x[0] - th)
    i_d, i_q = _stator(x[2], x[3], v_d, v_q, None, coef[P_XDP, c], coef[P_XQP, c])
    p_e = _powers(v_d, v_q, i_d, i_q)[0]  # (13)
    out[0] = _rotor_angle(x[1], ws)
    out[1] = _swing(pm, p_e, x[1], coef[P_D, c], coef[P_INV_2H, c])
    out[2] = _field_d(vf, x[2], i_d, coef[P_XD_DIFF, c], None, coef[P_INV_TD0, c])
    out[3] = _field_q(x[3], i_q, coef[P_XQ_DIFF, c], None, coef[P_INV_TQ0, c])


def _compiled_paper_step(sources: str) -> Any:
    """The compiled paper-model play-in, keyed to the equations' text as :func:`_compiled_step` is."""

    @maybe_jit
    def paper_steps(
        x0: Array, v_t: Array, theta: Array, p_m: Array, v_f: Array, coef: Array, ws: float, n_steps: int, h: float
    ) -> Array:
        _ = sources  # the key of the compiled code in numba's cache
        cols = x0.shape[1]
        states = np.empty((n_steps + 1, 4, cols))
        states[0] = x0
        h2, h6 = 0.5 * h, h / 6.0
        x = np.empty(4)
        xs = np.empty(4)
        k1, k2, k3, k4 = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
        for k in range(n_steps):
            a, b, e = 2 * k, 2 * k + 1, 2 * k + 2
            for c in range(cols):
                for i in range(4):
                    x[i] = states[k, i, c]
                _paper_rhs_column(x, k1, c, v_t[a, c], theta[a, c], p_m[a, c], v_f[a, c], coef, ws)
                for i in range(4):
                    xs[i] = x[i] + h2 * k1[i]
                _paper_rhs_column(xs, k2, c, v_t[b, c], theta[b, c], p_m[b, c], v_f[b, c], coef, ws)
                for i in range(4):
                    xs[i] = x[i] + h2 * k2[i]
                _paper_rhs_column(xs, k3, c, v_t[b, c], theta[b, c], p_m[b, c], v_f[b, c], coef, ws)
                for i in range(4):
                    xs[i] = x[i] + h * k3[i]
                _paper_rhs_column(xs, k4, c, v_t[e, c], theta[e, c], p_m[e, c], v_f[e, c], coef, ws)
                for i in range(4):
                    states[k + 1, i, c] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
        return states

    return paper_steps


_paper_rk4 = _compiled_paper_step(_sources_digest())
