"""Numerical building blocks shared by the simulator and the identification (numpy/scipy only).

The filters and the peak finder here are written on numpy and scipy.linalg, not taken from
scipy.signal: importing scipy.signal costs 0.8-1.8 s (scipy 1.17 parses every docstring of
its array-API wrappers at import), more than the whole identification of a recording, and
these three functions were all that identification used of it. Tests hold them equal to
scipy.signal's lfilter and find_peaks.

- :func:`first_order_response`: exact discretisation of ``T dx/dt = u - x`` for an
  input that is linear between samples (first-order hold), so flux ODEs driven
  by sampled currents are integrated without a half-sample bias.
- :func:`lowpass2` / :func:`lowpass2_derivative`: a critically damped
  second-order low-pass and its exact derivative, discretised by the bilinear
  map so that ``d/dt`` of the filtered signal and the filtered signal stay
  consistent to the sample (trapezoid rule).
- :func:`rk4`: fixed-step Runge-Kutta for right-hand sides vectorised over columns.
- :func:`uniform_grid` / :func:`interpolant`: the one way a recording is put onto a uniform
  grid (a recorder's jittered or off-cycle clock, a coarser rate, a coarse prediction).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from phid_ros import compiled_filters

Array = NDArray[np.float64]


def first_order_response(u: Array, tau: float, dt: float, axis: int = -1) -> Array:
    """Response ``L[u]`` of ``tau dx/dt = u - x`` from ``x(0) = 0``, with ``u`` linear between samples."""
    a, b0, b1 = first_order_coefficients(tau, dt)
    if np.ndim(u) == 1:
        y = compiled_filters.first_order_1d(np.asarray(u, dtype=float), a, b0, b1)
        if y is not None:
            return y
    u = np.moveaxis(np.asarray(u, dtype=float), axis, 0)
    v = b1 * u
    v[1:] += b0 * u[:-1]
    v[:1] = 0.0  # x(0) = 0: the recursion starts from rest (no free decay of a first value to remove)
    return np.moveaxis(recursive_first_order(v, a, axis=0), 0, axis)


def first_order_coefficients(tau: float, dt: float) -> tuple[float, float, float]:
    """(a, b0, b1) of :func:`first_order_response`: ``x[k] = a x[k-1] + b1 u[k] + b0 u[k-1]``."""
    a = float(np.exp(-dt / tau))
    b0 = (tau - (tau + dt) * a) / dt
    return a, b0, 1.0 - a - b0


def first_order_response_kept(u: Array, tau: float, dt: float, step: int) -> Array:
    """:func:`first_order_response` along the rows of a 2-D ``u``, only every ``step``-th sample."""
    a, b0, b1 = first_order_coefficients(tau, dt)
    y = compiled_filters.first_order_rows(u, a, b0, b1, step)
    return y if y is not None else first_order_response(u, tau, dt, axis=1)[:, ::step]


def recursive_first_order(x: Array, a: float, axis: int = -1) -> Array:
    """``y[n] = a y[n-1] + x[n]`` from rest along ``axis`` (scipy.signal.lfilter([1], [1, -a], x))."""
    return all_pole(x, (-a,), axis)


def all_pole(x: Array, a: tuple[float, ...], axis: int = -1) -> Array:
    """``y[n] = x[n] - a_1 y[n-1] - ... - a_k y[n-k]`` from rest: lfilter([1], [1, *a], x).

    The recursion compiled (:func:`phid_ros.compiled_filters.all_pole`) where numba is; else solved as
    the unit lower-triangular banded system it is, by LAPACK's banded triangular solve (forward
    substitution, all columns at once, no factorisation): the same steps, at lfilter's speed.
    """
    x = np.moveaxis(np.asarray(x, dtype=float), axis, 0)
    n = x.shape[0]
    if n == 0:
        return np.moveaxis(x.copy(), 0, axis)
    rhs = x if x.ndim == 2 else x.reshape(n, -1)  # 2-D: a column-major view, no copy for axis=1 input
    y = compiled_filters.all_pole(rhs, a)
    if y is not None:
        return np.moveaxis(y.reshape(x.shape), 0, axis)
    from scipy.linalg.lapack import dtbtrs  # here: with numba, identification does without scipy.linalg

    band = np.empty((len(a) + 1, n), order="F")  # LAPACK's layout: no copy on the way in
    band[0] = 1.0  # the unit diagonal (diag="U": not read)
    for i, ai in enumerate(a, start=1):
        band[i] = ai
    y, info = dtbtrs(band, rhs, uplo="L", diag="U")
    if info != 0:
        raise ValueError(f"banded triangular solve failed (LAPACK info {info})")
    return np.moveaxis(y.reshape(x.shape), 0, axis)


def free_decay(n: int, tau: float, dt: float, start: int = 0) -> Array:
    """``exp(-(t - t_start)/tau)`` from sample ``start`` on, zero before."""
    out = np.zeros(n)
    k = np.arange(n - start)
    out[start:] = np.exp(-k * dt / tau)
    return out


def lowpass2_coefficients(fc: float, dt: float, derivative: bool) -> tuple[Array, Array]:
    """The bilinear map of ``w^2 / (s^2 + 2 w s + w^2)`` (times ``s`` for the derivative), written out.

    ``s = K (z - 1)/(z + 1)`` with ``K = 2/dt``: scipy.signal.bilinear's coefficients (test).
    """
    w = 2.0 * np.pi * fc
    k = 2.0 / dt
    a = np.array([k * k + 2.0 * w * k + w * w, 2.0 * (w * w - k * k), k * k - 2.0 * w * k + w * w])
    b = w * w * (np.array([k, 0.0, -k]) if derivative else np.array([1.0, 2.0, 1.0]))
    return b / a[0], a / a[0]


def _lowpass2_from_rest(x: Array, fc: float, dt: float, derivative: bool, axis: int) -> Array:
    """The section as its numerator taps, then its denominator as one all-pole recursion."""
    b, a = lowpass2_coefficients(fc, dt, derivative)
    x = np.moveaxis(np.asarray(x, dtype=float), axis, 0)
    v = b[0] * x
    v[1:] += b[1] * x[:-1]
    if b[2]:
        v[2:] += b[2] * x[:-2]
    return np.moveaxis(all_pole(v, (float(a[1]), float(a[2])), axis=0), 0, axis)


def lowpass2(x: Array, fc: float, dt: float, *, steady_start: bool = False, axis: int = -1) -> Array:
    """Critically damped second-order low-pass at ``fc`` Hz.

    ``steady_start`` starts the filter in steady state at the first value (no
    start-up transient); the default starts from rest, which keeps the filter
    exactly linear (needed when it is applied to the terms of an equation).
    """
    if steady_start:
        # the section passes a constant unchanged (gain 1 at DC): the steady state at the first
        # value is that value, and the rest is the response to the departure from it
        x0 = np.take(x, [0], axis=axis)
        return _lowpass2_from_rest(x - x0, fc, dt, False, axis) + x0
    return _lowpass2_from_rest(x, fc, dt, False, axis)


def lowpass2_derivative(x: Array, fc: float, dt: float, axis: int = -1) -> Array:
    """d/dt of :func:`lowpass2` (from rest), exact in the discrete sense."""
    return _lowpass2_from_rest(x, fc, dt, True, axis)


def find_peaks(x: Array, distance: int = 1) -> NDArray[np.intp]:
    """Indices of the local maxima of ``x`` at least ``distance`` samples apart, the higher kept first.

    scipy.signal.find_peaks(x, distance=...) (a test holds them equal): a plateau counts once,
    at its middle; a maximum at either end of ``x`` is not a peak.
    """
    x = np.asarray(x, dtype=float)
    n = len(x)
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    d = np.diff(x)
    if np.all(d != 0):
        peaks = np.flatnonzero((d[:-1] > 0) & (d[1:] < 0)) + 1
    else:
        peaks = _local_maxima_with_plateaus(x)
    if distance <= 1 or len(peaks) < 2:
        return peaks
    keep = np.ones(len(peaks), dtype=bool)
    for j in np.argsort(x[peaks])[::-1]:  # highest first, as scipy (its order among equal heights too)
        if not keep[j]:
            continue
        k = j - 1
        while k >= 0 and peaks[j] - peaks[k] < distance:
            keep[k] = False
            k -= 1
        k = j + 1
        while k < len(peaks) and peaks[k] - peaks[j] < distance:
            keep[k] = False
            k += 1
    return peaks[keep]


def _local_maxima_with_plateaus(x: Array) -> NDArray[np.intp]:
    peaks = []
    i, n = 1, len(x)
    while i < n - 1:
        if x[i - 1] < x[i]:
            ahead = i + 1
            while ahead < n - 1 and x[ahead] == x[i]:
                ahead += 1
            if x[ahead] < x[i]:
                peaks.append((i + ahead - 1) // 2)
                i = ahead
        i += 1
    return np.array(peaks, dtype=np.intp)


def rk4(
    rhs: Callable[..., Array],
    x0: Array,
    n_steps: int,
    dt: float,
    inputs: Callable[[int], tuple],
    out: Array | None = None,
    staged: Callable[[int, int], tuple] | None = None,
) -> Array:
    """Integrate ``dx/dt = rhs(x, *u)``; returns states (n+1, ...).

    By default the inputs ``inputs(k)`` are held over step k (a sampled plant's
    zero-order hold). With ``staged``, ``staged(k, j)`` gives the inputs at
    t_k + j h/2 (j = 0, 1, 2), so RK4 keeps its fourth order on sampled signals.
    """
    x = np.array(x0, dtype=float)
    states = out if out is not None else np.empty((n_steps + 1,) + x.shape)
    states[0] = x
    h2, h6 = 0.5 * dt, dt / 6.0
    for k in range(n_steps):
        if staged is None:
            a = b = c = inputs(k)
        else:
            a, b, c = staged(k, 0), staged(k, 1), staged(k, 2)
        k1 = rhs(x, *a)
        k2 = rhs(x + h2 * k1, *b)
        k3 = rhs(x + h2 * k2, *b)
        k4 = rhs(x + dt * k3, *c)
        x = x + h6 * (k1 + 2.0 * (k2 + k3) + k4)
        states[k + 1] = x
    return states


def uniform_grid(start: float, end: float, period: float) -> Array:
    """``start``, ``start + period``, ... up to ``end`` inclusive (an ``end`` that rounding puts a
    hair past the last step is still on it): the times a recording is resampled onto."""
    grid = start + np.arange(0.0, end - start + 0.5 * period, period)
    return grid[grid <= end]


def interpolant(
    t: NDArray[np.floating[Any]], x: NDArray[np.floating[Any]], how: Literal["linear", "cubic"] = "linear"
) -> Callable[[NDArray[np.floating[Any]]], Array]:
    """``x``, sampled at the increasing times ``t``, as a function of time.

    ``linear`` for phasors and slow values (smooth at their report rate; never overshoots a
    step), ``cubic`` for waveforms: a cubic spline through samples ``h`` apart misses a sinusoid
    of angular frequency ``w`` by at most 5/384 (w h)^4 of its amplitude. Built once, read at
    any times (a file read in parts reads one channel's interpolant part by part).
    """
    if how == "cubic":
        from scipy.interpolate import CubicSpline  # where a waveform needs it, not at every import

        spline = CubicSpline(t, x)
        return lambda at: np.asarray(spline(at), dtype=np.float64)
    if how != "linear":
        raise ValueError(f"interpolant: how={how!r}, expected 'linear' or 'cubic'")
    return lambda at: np.interp(at, t, x)
