"""The play-in's integration compiled (numba): the plant's equations per column, in one loop.

Why: a diagnosis integrates the plant millions of steps on a few dozen columns, where numpy
spends its time on the call overhead of some forty small array operations per right-hand
side, not on arithmetic (a run of one model cost nearly what a run of a dozen did). Compiled,
the same steps take a few percent of that time.

What: the generator model (5)-(13) of :class:`~phid_ros.sim.plant.Plant` with the stator
resistance and every registered effect that declares compiled terms (``PlantEffect.compiled``),
driven by the measured terminal phasor (no network: the play-in's zero-impedance source).
Nothing of an effect is written here: the kernel is built from the registry when it is
imported, each effect's rows of coefficients placed after the base model's and its compiled
functions called at their place in a column's right-hand side (:func:`_compose`), so an
effect with compiled equations is one module of :mod:`phid_ros.sim.effects`. The base
model's equations are ``model/equations``' and ``model/conventions``' functions compiled as
written (:mod:`phid_ros.sim.jitted`); this module only says in which order a column calls them.
The numpy plant (``Plant._rhs`` with the effects' hooks) stays the reference: a test runs
both on every effect combination and holds them equal to rounding, and :func:`integrate`
returns None, so the caller falls back to numpy, when numba is not installed, when
``PHID_NO_JIT`` is set, or when an effect has no compiled terms.
"""

from __future__ import annotations

import hashlib
import inspect
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cache, partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.jit import available, compile_once, f64, i64, maybe_jit
from phid_ros.model import conventions, equations
from phid_ros.sim import effects, jitted
from phid_ros.sim.effects.base import PlantEffect

Array = NDArray[np.float64]

# rows of the per-column coefficient matrix: the base model's, then each compiled effect's own
BASE_ROWS = (
    "inv_2h",
    "xd_diff",
    "xq_diff",
    "inv_td0",
    "inv_tq0",
    "x_d_prime",
    "x_q_prime",
    "r_a",
    "damping",
    "x_series",  # the network's reactance between the terminal and the source (0: the play-in's)
)
# the same indices as constants, which the compiled code reads as literals
INV_2H, XD_DIFF, XQ_DIFF, INV_TD0, INV_TQ0, XDP, XQP, R_A, DAMPING, X_SERIES = range(len(BASE_ROWS))


def compiled_parts(classes: Any) -> list[tuple[type[PlantEffect], int]]:
    """The effects with compiled terms among ``classes`` (in their order), each with the first row
    of its coefficients."""
    parts, row = [], len(BASE_ROWS)
    for cls in classes:
        if cls.compiled is not None:
            parts.append((cls, row))
            row += len(cls.compiled.rows)
    return parts


PARTS = compiled_parts(effects.REGISTRY.values())  # the kernel's effects: every registered one that compiles
N_ROWS = len(BASE_ROWS) + sum(len(cls.compiled.rows) for cls, _ in PARTS if cls.compiled is not None)
PART_OF = {cls: k for k, (cls, _) in enumerate(PARTS)}

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
    x_series: Array | float = 0.0,
) -> Array | None:
    """RK4 of ``plant`` from ``x0`` (n_states, cols): its OUTPUTS (6, n_steps + 1, cols), or None.

    ``staged`` = (P_m, V_f, V_t, theta_t) at every half step (rows 2k + j at t_k + j h/2),
    as :func:`phid_ros.numerics.rk4` reads them; ``source[i, c]`` is the column of input ``i``
    that model column ``c`` reads (models of one scenario share its measured inputs unless an
    effect re-times them per model). The outputs at step k are the plant's at its state x_k and
    the inputs of row 2k (the play-in's terminal is the source: V = V_th), computed where the
    step computes them anyway, so no trajectory of states is stored. None when the compiled
    path cannot run. ``threads``: the columns split over this many threads (the compiled loop
    holds no GIL, and each column's arithmetic is the same wherever it runs). ``x_series``: a
    reactance per column between the terminal and the source (then P and Q are the terminal's,
    and V_t is the source's plus the drop, :func:`phid_ros.sim.network.terminal_dq`).
    """
    args = _column_args(plant, x0, n_steps, h, staged, source, damping, x_series)
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
    x_series: Array | float = 0.0,
) -> Callable[[int, int], tuple[Any, ...]] | None:
    """The compiled loops' common arguments for the model columns a:b, or None where the
    compiled path cannot run (numba absent or switched off, an effect without compiled terms)."""
    if not available():
        return None
    terms = _terms(plant, x0.shape[1], damping)
    if terms is None:
        return None
    coef, at = terms
    coef[X_SERIES] = np.broadcast_to(np.asarray(x_series, dtype=np.float64), (x0.shape[1],))
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
            at,
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


def _terms(plant: Any, cols: int, damping: Array) -> tuple[Array, NDArray[np.int64]] | None:
    """The coefficient matrix (N_ROWS, cols) and each compiled effect's ``at`` (-1: not in this
    plant), or None for a plant the kernel has no terms for."""
    coef = np.zeros((N_ROWS, cols))
    at = np.full(len(PARTS), -1, dtype=np.int64)

    def put(row: int, value: Any) -> None:
        coef[row] = np.broadcast_to(np.asarray(value, dtype=np.float64), (cols,))

    for row, name in enumerate(BASE_ROWS[:7]):
        put(row, getattr(plant.coef, name))
    put(R_A, plant.r_a)
    put(DAMPING, damping)
    for effect, sl in zip(plant.effects, plant.slots):
        found = effect.kernel_terms(plant)
        if found is None:
            return None
        cls = type(effect)
        if cls.compiled is None:
            continue  # acts through the plant's constants or the measurements only
        k = PART_OF.get(cls)
        if k is None:
            return None  # registered after this kernel was built: the numpy plant runs it
        first = PARTS[k][1]
        for i, name in enumerate(cls.compiled.rows):
            put(first + i, found[name])
        at[k] = effect.kernel_setting(plant, sl)
    return coef, at


# inlined: the step calls the column's right-hand side four times, and as a call each passed
# three arrays and a dozen scalars: 1.5x the time
_maybe_jit_inlined = partial(maybe_jit, inline=True)
# the links of the composition below: closures over the effects' functions, inlined into the
# cached step (see _compiled_step); on their own they are never cached (a closure over a
# compiled function gets a new key in every process)
_link_jit = partial(maybe_jit, inline=True, cache=False)


def _base_emf(x: Array, coef: Array, c: int, at: NDArray[np.int64]) -> tuple[float, float, float, float]:
    return x[2], x[3], coef[XDP, c], coef[XQP, c]  # the fourth-order model: E'_q, E'_d behind X'_d, X'_q


def _no_losses(
    x: Array, out: Array, coef: Array, c: int, at: NDArray[np.int64], psi_d: float, psi_q: float, i_d: float, i_q: float
) -> tuple[float, float]:
    return 0.0, 0.0


def _base_swing(
    x: Array,
    out: Array,
    coef: Array,
    c: int,
    at: NDArray[np.int64],
    d_omega: float,
    p_m: float,
    p_airgap: float,
    damping: float,
    ws: float,
) -> float:
    return d_omega


def _emf_link(prev: Any, hook: Any, k: int, r: int) -> Any:
    def emf(x: Array, coef: Array, c: int, at: NDArray[np.int64]) -> tuple[float, float, float, float]:
        if at[k] >= 0:
            return hook(x, coef, c, r, at[k])
        return prev(x, coef, c, at)

    return _link_jit(emf)


def _losses_link(prev: Any, hook: Any, k: int, r: int) -> Any:
    def losses(
        x: Array,
        out: Array,
        coef: Array,
        c: int,
        at: NDArray[np.int64],
        psi_d: float,
        psi_q: float,
        i_d: float,
        i_q: float,
    ) -> tuple[float, float]:
        loss_d, loss_q = prev(x, out, coef, c, at, psi_d, psi_q, i_d, i_q)
        if at[k] >= 0:
            d, q = hook(x, out, coef, c, r, at[k], psi_d, psi_q, i_d, i_q)
            loss_d = loss_d + d
            loss_q = loss_q + q
        return loss_d, loss_q

    return _link_jit(losses)


def _swing_link(prev: Any, hook: Any, k: int, r: int) -> Any:
    def swing(
        x: Array,
        out: Array,
        coef: Array,
        c: int,
        at: NDArray[np.int64],
        d_omega: float,
        p_m: float,
        p_airgap: float,
        damping: float,
        ws: float,
    ) -> float:
        d = prev(x, out, coef, c, at, d_omega, p_m, p_airgap, damping, ws)
        if at[k] >= 0:
            d = hook(x, out, coef, c, r, at[k], p_m, p_airgap, damping, ws)
        return d

    return _link_jit(swing)


def _compose(parts: list[tuple[type[PlantEffect], int]]) -> tuple[Any, Any, Any]:
    """The right-hand side's three places for effects, each a chain over the compiled effects in
    the registry's order: the EMF behind the stator reactances (the last effect present that
    provides one), the losses in the field equations (summed in that order, as the numpy plant
    sums its hooks'), and the rotor's swing (the last present that replaces it)."""
    emf, losses, swing = _link_jit(_base_emf), _link_jit(_no_losses), _link_jit(_base_swing)
    for k, (cls, r) in enumerate(parts):
        part = cls.compiled
        assert part is not None
        if part.emf is not None:
            emf = _emf_link(emf, _maybe_jit_inlined(part.emf), k, r)
        if part.losses is not None:
            losses = _losses_link(losses, _maybe_jit_inlined(part.losses), k, r)
        if part.swing is not None:
            swing = _swing_link(swing, _maybe_jit_inlined(part.swing), k, r)
    return emf, losses, swing


_emf, _losses, _swing_of = _compose(PARTS)


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
    at: NDArray[np.int64],
    ws: float,
) -> tuple[float, float, float, float]:
    """dx/dt of one column: ``Plant._rhs`` with the effects' hooks, in the same order.

    Returns the stator solution it used, (I_d, I_q, V_d, V_q), for the outputs."""
    delta, omega, e_q, e_d = x[0], x[1], x[2], x[3]
    eq_i, ed_i, xd_i, xq_i = _emf(x, coef, c, at)
    v_d, v_q = jitted.dq_of(vt, delta - th)
    x_s = coef[X_SERIES, c]
    i_d, i_q = jitted.stator(eq_i, ed_i, v_d, v_q, coef[R_A, c], xd_i + x_s, xq_i + x_s)
    # the terminal: the source's voltage plus the drop through the reactance (terminal_dq, R = 0)
    v_d, v_q = v_d - x_s * i_q, v_q + x_s * i_d
    p_airgap = jitted.airgap_power(eq_i, ed_i, i_d, i_q, xd_i, xq_i)
    damping = coef[DAMPING, c]
    d_omega = jitted.swing(pm, p_airgap, omega, damping, coef[INV_2H, c])
    loss_d, loss_q = _losses(x, out, coef, c, at, eq_i, ed_i, i_d, i_q)
    out[0] = jitted.rotor_angle(omega, ws)
    out[2] = jitted.field_d(vf, e_q, i_d, coef[XD_DIFF, c], loss_d, coef[INV_TD0, c])
    out[3] = jitted.field_q(e_d, i_q, coef[XQ_DIFF, c], loss_q, coef[INV_TQ0, c])
    out[1] = _swing_of(x, out, coef, c, at, d_omega, pm, p_airgap, damping, ws)
    return i_d, i_q, v_d, v_q


def _digest(files: Any, extra: str = "") -> str:
    digest = hashlib.sha256(extra.encode())
    for path in sorted({str(f) for f in files}):
        digest.update(Path(path).read_bytes())
    return digest.hexdigest()


def _equation_files() -> list[str]:
    return [str(conventions.__file__), str(equations.__file__), str(jitted.__file__)]


def _sources_digest(parts: list[tuple[type[PlantEffect], int]] | None = None) -> str:
    """The text of every file whose functions the step compiles (see :func:`_compiled_step`): the
    model's equations, and each compiled effect's module and functions; and the composition
    itself (which effects, in which order, at which rows)."""
    parts = PARTS if parts is None else parts
    files = _equation_files() + [str(inspect.getsourcefile(effects.base))]
    for cls, _ in parts:
        files.append(str(inspect.getsourcefile(cls)))
        assert cls.compiled is not None
        files += [
            str(inspect.getsourcefile(f)) for f in (cls.compiled.emf, cls.compiled.losses, cls.compiled.swing) if f
        ]
    return _digest(files, repr([(cls.__module__, cls.__qualname__, r) for cls, r in parts]))


# a call, not inlined: both loops below call it, and inlined its four right-hand sides were
# optimised twice on a first run (13.8 s against 5.8 s; the same speed once compiled). Never
# cached on its own: the loops' cached code holds it
@partial(maybe_jit, cache=False)
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
    at: NDArray[np.int64],
    ws: float,
    h: float,
    work: Array,
    res: Array,
) -> None:
    """One RK4 step of column ``c`` from step ``k``: its OUTPUTS at x_k into ``res``, x_{k+1} into
    ``xall`` (not after the ``last`` step). ``work`` holds six state vectors (x, a stage, k1-k4)."""
    n_states = xall.shape[0]
    x, xs = work[0], work[1]
    pm, vf, vt, th = source[0, c], source[1, c], source[2, c], source[3, c]
    h2, h6 = 0.5 * h, h / 6.0
    for i in range(n_states):
        x[i] = xall[i, c]
    # the four stages in one loop, so the right-hand side (inlined) is compiled once, not four
    # times: a first run's compile of the step fell from 4.8 s to 1.x s, the arithmetic unchanged
    for stage in range(4):
        if stage == 0:
            for i in range(n_states):
                xs[i] = x[i]
        else:
            prev = work[1 + stage]  # k_1, k_2, k_3
            scale = h if stage == 3 else h2
            for i in range(n_states):
                xs[i] = x[i] + scale * prev[i]
        row = 2 * k if stage == 0 else (2 * k + 2 if stage == 3 else 2 * k + 1)  # t_k, t_k + h/2, t_k + h
        i_d, i_q, v_d, v_q = _rhs_column(
            xs, work[2 + stage], c, p_m[row, pm], v_f[row, vf], v_t[row, vt], theta[row, th], coef, at, ws
        )
        if stage == 0:
            res[0] = x[0]
            res[1] = x[1]
            res[2] = i_d
            res[3] = i_q
            res[4], res[5] = jitted.powers(v_d, v_q, i_d, i_q)  # P_e (13) and Q_e
            if last:
                return
    k1, k2, k3, k4 = work[2], work[3], work[4], work[5]
    for i in range(n_states):
        xall[i, c] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


def _outputs_kernel(sources: str) -> Any:
    """The play-in's step loop (to be compiled), closed over ``sources`` (see _compiled_step)."""

    def rk4_outputs(
        x0: Array,
        p_m: Array,
        v_f: Array,
        v_t: Array,
        theta: Array,
        source: NDArray[np.int64],
        coef: Array,
        at: NDArray[np.int64],
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
                _column_step(xall, c, k, k == n_steps, p_m, v_f, v_t, theta, source, coef, at, ws, h, work, res)
                for q in range(6):
                    out[q, k, c] = res[q]
        return out

    return rk4_outputs


def _residuals_kernel(sources: str) -> Any:
    """The fit's residual loop (to be compiled), closed over ``sources`` (see _compiled_step)."""

    def rk4_residuals(
        x0: Array,
        p_m: Array,
        v_f: Array,
        v_t: Array,
        theta: Array,
        source: NDArray[np.int64],
        coef: Array,
        at: NDArray[np.int64],
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
                _column_step(xall, c, k, k == n - 1, p_m, v_f, v_t, theta, source, coef, at, ws, h, work, res)
                i = (c0 + c) % m
                row = rows_at[j] + k
                for q in range(6):
                    out[row + q * n, i] = (res[order[q]] - meas[k, msource[q, c]]) / sigma[q]

    return rk4_residuals


def _compiled_step(sources: str) -> Any:
    """The compiled RK4 play-in, keyed in numba's cache to ``sources`` as well as to this file.

    Why: the step compiles equations written in other files, and numba's cache looks only at
    the file of the function it caches; an edited equation would be served from the old code.
    A closure's variables are part of numba's cache key, so the step closes over the digest
    of those files' text. One signature each (inputs read-only, any layout: the fit's residual
    matrix is C or Fortran order), so a first diagnosis compiles each once.
    """
    from numba import types

    scalars = (types.float64, types.int64, types.float64)  # ws, n_steps, h
    common = (f64(2, True), *(f64(2, True),) * 4, i64(2, True), f64(2, True), i64(1, True), *scalars)
    layout = (f64(2, True), i64(2, True), i64(1, True), f64(1, True), i64(1, True), i64(1, True))
    return (
        compile_once(_outputs_kernel(sources), *common),
        compile_once(_residuals_kernel(sources), *common, *layout, types.int64, types.int64, f64(2)),
    )


@cache
def _step_kernels() -> tuple[Any, Any]:
    """(rk4_outputs, rk4_residuals), compiled or loaded from numba's cache on the first play-in."""
    return _compiled_step(_sources_digest())


def _rk4_outputs(*args: Any) -> Array:
    return _step_kernels()[0](*args)


def _rk4_residuals(*args: Any) -> None:
    _step_kernels()[1](*args)


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
    v_d, v_q = jitted.dq_of(vt, x[0] - th)
    i_d, i_q = jitted.stator(x[2], x[3], v_d, v_q, None, coef[P_XDP, c], coef[P_XQP, c])
    p_e = jitted.powers(v_d, v_q, i_d, i_q)[0]  # (13)
    out[0] = jitted.rotor_angle(x[1], ws)
    out[1] = jitted.swing(pm, p_e, x[1], coef[P_D, c], coef[P_INV_2H, c])
    out[2] = jitted.field_d(vf, x[2], i_d, coef[P_XD_DIFF, c], None, coef[P_INV_TD0, c])
    out[3] = jitted.field_q(x[3], i_q, coef[P_XQ_DIFF, c], None, coef[P_INV_TQ0, c])


def _compiled_paper_step(sources: str) -> Any:
    """The compiled paper-model play-in, keyed to the equations' text as :func:`_compiled_step` is."""

    @maybe_jit
    def paper_steps(
        x0: Array, v_t: Array, theta: Array, p_m: Array, v_f: Array, coef: Array, ws: float, n_steps: int, h: float
    ) -> Array:
        _ = sources  # the key of the compiled code in numba's cache
        cols = x0.shape[1]
        states = np.empty((n_steps + 1, 4, cols))
        # element by element: an array assignment compiles numba's shape-mismatch message (string
        # formatting), 3 s of a first run's compile
        for i in range(4):
            for c in range(cols):
                states[0, i, c] = x0[i, c]
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


_paper_rk4 = _compiled_paper_step(_digest(_equation_files()))
