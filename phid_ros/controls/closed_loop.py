"""The voltage regulator's loop closed through the machine in a play-in.

A play-in that drives the exciter by the *recorded* V_t leaves its loop open: the exciter's
output never acts back on what it reads, so a thousandth of a pu the model reads differently
(the stabiliser's output, a lead-lag's tail) is held by a regulator of DC gain in the hundreds
for seconds, and the field it makes drifts tenths of a pu from the recorded one (Mostar's PSS-on
return: Q 0.11 pu off, for the published record too). The unit on its network corrects it: the
field moves V_t, and the regulator reads it.

Here the machine stands behind a reactance (the network's, :mod:`phid_ros.ident.network_equivalent`,
or an open breaker's at no load) from the source the recording gives
(:func:`phid_ros.ident.plant_playin.behind_reactance`), and the terminal voltage V is the one that
both the machine makes from the field the exciter makes from V:

    V = F(V),    F = machine after exciter.

The exciter and the machine are simulated whole (each over the recording), so the fixed point is
found by Newton's method over the waveform: V <- V - J^-1 (V - F(V)), with J = 1 - dF/dV taken
from the two linear responses (the exciter's to a step of V_t, the machine's to a step of E_fd,
both from rest), a lower-triangular Toeplitz operator whose inverse is one kernel worked out once.
Where a limit holds the exciter (Mostar's regulator sits on its ceiling in every AVR step) the
loop's gain is not the linear one and those steps alone crawl (|V - F(V)| 0.004 pu after ten);
Anderson's mixing of the last few iterates takes that in (Mostar: 6-7 iterations to 1e-4 pu).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import fftconvolve

from phid_ros.ident.plant_playin import BehindReactance

Array = NDArray[np.float64]

TOLERANCE_PU = 1e-4  # |V - F(V)| at which the loop is closed: a tenth of a recorder's V_t resolution
MAX_ITERATIONS = 25
MEMORY = 6  # iterates Anderson's mixing looks back over
PROBE_PU = 0.01  # the E_fd step the machine's linear response is measured with
# J^-1's kernel is worked out this far (33 s at the play-in's 4 ms): its cost grows with the square
# of its length, and the settled loop's memory is far shorter; what a cut tail leaves, the
# iterations take
KERNEL_SAMPLES = 8192


class LoopNotClosed(RuntimeError):
    """The fixed point was not found: the loop (as the models draw it) does not settle on the recording."""


@dataclass
class ClosedLoop:
    """The unit's field and terminal with its loop closed."""

    v_f: Array  # E_fd on every sample of the recording (pu)
    run: BehindReactance  # the machine's V_t, P, Q on the play-in grid
    iterations: int
    residual: float  # max |V - F(V)| at the end (pu)


def increments(step_response: Array) -> Array:
    """A linear response's per-sample kernel from its unit-step response (sample 0 first)."""
    return np.diff(step_response, prepend=0.0)


def inverse_kernel(j: Array) -> Array:
    """The kernel c with c * j = unit impulse (both causal, on one grid): J^-1 of a lower-
    triangular Toeplitz operator, by forward substitution."""
    n = len(j)
    c = np.zeros(n)
    c[0] = 1.0 / j[0]
    for k in range(1, n):
        c[k] = -np.dot(j[1 : k + 1], c[k - 1 :: -1]) / j[0]
    return c


def close_loop(
    v_recorded: Array,
    exciter: Callable[[Array], Array],
    exciter_step: Array,
    machine: Callable[[list[Array]], list[BehindReactance]],
) -> ClosedLoop:
    """The loop's fixed point (see the module's note).

    ``v_recorded``: V_t on every sample (where the iterations start); ``exciter``: E_fd on every
    sample from V_t on every sample; ``exciter_step``: its linear response (E_fd per pu of V_t,
    negative for a regulator) to a unit step of V_t at sample 0, on every sample; ``machine``: the
    machine behind its reactance for each E_fd given. Raises :class:`LoopNotClosed`."""
    n = len(v_recorded)
    samples = np.arange(n)

    def on_every_sample(idx: Array, v: Array) -> Array:
        return np.interp(samples, idx, v)

    e = exciter(v_recorded)
    first, probed = machine([e, e + PROBE_PU])
    idx = first.idx
    mv = increments((probed.v_t - first.v_t) / PROBE_PU)
    g = increments(exciter_step[idx])
    j = -fftconvolve(mv, g)[: min(len(idx), KERNEL_SAMPLES)]
    j[0] += 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        c = inverse_kernel(j)
    if not np.isfinite(c).all():  # a loop whose linear gain grows without bound (T_R 1e-9 s, T_C1 = T_B1 = 1e6 s)
        raise LoopNotClosed("the voltage loop's linear kernel grows without bound (the loop is unstable as drawn)")

    v = np.asarray(v_recorded, float)[idx]
    run = first
    r = v - run.v_t
    # an unstable loop's iterates overflow before the residual shows it: not finite is the verdict
    # (LoopNotClosed below), not numpy's warnings on the way there
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return _iterate(v, e, run, r, c, idx, exciter, machine, on_every_sample)


def _iterate(
    v: Array,
    e: Array,
    run: BehindReactance,
    r: Array,
    c: Array,
    idx: Array,
    exciter: Callable[[Array], Array],
    machine: Callable[[list[Array]], list[BehindReactance]],
    on_every_sample: Callable[[Array, Array], Array],
) -> ClosedLoop:
    """Newton's steps through the kernel ``c`` with Anderson's mixing, from ``v`` (its field ``e``,
    the machine's ``run``, the residual ``r``)."""
    worst = float(np.max(np.abs(r)))
    tried: list[Array] = []  # the iterates and their Newton steps, for Anderson's mixing
    steps: list[Array] = []
    iterations = 0
    while not worst <= TOLERANCE_PU:  # a NaN residual is no fixed point (it ended this loop "closed")
        if iterations == MAX_ITERATIONS or not np.isfinite(worst):
            raise LoopNotClosed(
                f"the voltage loop did not close in {MAX_ITERATIONS} iterations (|V - F(V)| {worst:.2g} pu)"
            )
        iterations += 1
        newton = -fftconvolve(c, r)[: len(idx)]
        tried.append(v)
        steps.append(newton)
        v = v + newton
        if len(tried) > 1:
            # where a limit holds the exciter, its loop gain is not the linear one the step assumed:
            # the last few iterates show it, and their least-squares mix takes it in
            dv = np.diff(np.array(tried[-MEMORY - 1 :]), axis=0).T
            dn = np.diff(np.array(steps[-MEMORY - 1 :]), axis=0).T
            try:
                gamma = np.linalg.lstsq(dn, newton, rcond=None)[0]
            except np.linalg.LinAlgError as exc:  # iterates no longer finite
                raise LoopNotClosed(f"the voltage loop diverged after {iterations} iterations ({exc})") from None
            v = v - (dv + dn) @ gamma
        e = exciter(on_every_sample(idx, v))
        [run] = machine([e])
        r = v - run.v_t
        worst = float(np.max(np.abs(r)))
    return ClosedLoop(e, run, iterations, worst)
