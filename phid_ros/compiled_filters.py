"""The filters' recursions compiled (the ``[jit]`` extra), for :mod:`phid_ros.numerics`.

Each function returns None where numba is not available (or ``PHID_NO_JIT`` is set), and
numerics runs its numpy or LAPACK path instead; tests hold the two together. Below numerics
and beside the simulator's kernel: both stage 3 and the play-in filter, neither owns this.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.jit import available, f64, njit

Array = NDArray[np.float64]


def all_pole(x: Array, a: tuple[float, ...]) -> Array | None:
    """``y[n] = x[n] - a_1 y[n-1] - ... - a_k y[n-k]`` from rest down each column of a 2-D
    ``x`` (n, m), compiled; None when numba is not there (or ``PHID_NO_JIT``).

    Why: LAPACK's banded triangular solve that :func:`phid_ros.numerics.all_pole` uses spent
    4-7 ns a sample (0.8 ms on a stage-3 block of 15 columns of 13 000 samples, 0.09 s of a
    catalogue identification); this loop is about one multiply-add chain per sample. The sums
    are taken in the solve's order (the oldest output first), so the two differ only where
    OpenBLAS fuses a multiply-add (1e-14 relative; a test holds them together).
    """
    global _all_pole_compiled
    if not available():
        return None
    if _all_pole_compiled is None:
        # one signature, any layout ("A"), loaded from numba's cache on first use: left to numba,
        # each layout met (C, F, strided) compiles and loads its own copy, 25 ms each per process
        from numba import types

        sig = types.void(f64(2, True), f64(1, True), f64(2))
        _all_pole_compiled = njit(sig, cache=True, nogil=True)(_all_pole_columns)
    y = np.empty(x.shape, order="F")
    _all_pole_compiled(np.asarray(x, dtype=np.float64), np.asarray(a, dtype=np.float64), y)
    return y


_all_pole_compiled: Any = None


def _all_pole_columns(x: Array, a: Array, y: Array) -> None:
    n, m = x.shape
    k = a.shape[0]
    for j in range(m):
        if k == 1:  # stage 3's first-order recursions: one chain, no inner loop
            a1 = a[0]
            prev = 0.0
            for i in range(n):
                prev = x[i, j] - a1 * prev
                y[i, j] = prev
        elif k == 2:  # the second-order low-passes
            a1, a2 = a[0], a[1]
            p1 = 0.0
            p2 = 0.0
            for i in range(n):
                v = (x[i, j] - a2 * p2) - a1 * p1
                y[i, j] = v
                p2 = p1
                p1 = v
        else:
            for i in range(n):
                v = x[i, j]
                for q in range(min(k, i), 0, -1):
                    v -= a[q - 1] * y[i - q, j]
                y[i, j] = v


def first_order_1d(u: Array, a: float, b0: float, b1: float) -> Array | None:
    """:func:`phid_ros.numerics.first_order_response` of a 1-D ``u``, compiled; None without
    numba (or ``PHID_NO_JIT``).

    Why: the control systems' fits filter each case (a few hundred samples) hundreds of
    thousands of times (Zakucac's 30 polled steps: 861 000 calls); numpy's input stage and the
    axis moves around the recursion took 49 of the 54 us a call. The same operations in the same
    order as that input stage and :func:`all_pole`, so the result is theirs bit for bit (a test).
    """
    global _first_order_1d_compiled
    if not available():
        return None
    if _first_order_1d_compiled is None:
        from numba import types

        sig = types.void(f64(1, True), types.float64, types.float64, types.float64, f64(1))
        _first_order_1d_compiled = njit(sig, cache=True, nogil=True)(_first_order_1d)
    out = np.empty(u.shape[0])
    if u.shape[0]:
        _first_order_1d_compiled(np.asarray(u, dtype=np.float64), float(a), float(b0), float(b1), out)
    return out


_first_order_1d_compiled: Any = None


def _first_order_1d(u: Array, a: float, b0: float, b1: float, out: Array) -> None:
    a1 = -a
    prev = 0.0
    out[0] = 0.0  # x(0) = 0: from rest
    for i in range(1, u.shape[0]):
        v = b1 * u[i]
        v += b0 * u[i - 1]
        prev = v - a1 * prev
        out[i] = prev


def first_order_rows(u: Array, a: float, b0: float, b1: float, step: int) -> Array | None:
    """:func:`phid_ros.numerics.first_order_response` along each row of ``u`` (m, n), kept at
    every ``step``-th sample (m, ceil(n / step)), compiled; None without numba (or ``PHID_NO_JIT``).

    Why: stage 3 filters every scenario's current at every trial time constant and reads one
    sample in five; the first-order-hold input, the recursion and the decimation in one pass
    skip three full-length temporaries. The same operations in the same order as the numpy
    input stage and :func:`all_pole`, so the kept samples are theirs bit for bit (a test).
    """
    global _first_order_rows_compiled
    if not available():
        return None
    if _first_order_rows_compiled is None:
        from numba import types

        sig = types.void(f64(2, True), types.float64, types.float64, types.float64, types.int64, f64(2))
        _first_order_rows_compiled = njit(sig, cache=True, nogil=True)(_first_order_rows)
    m, n = u.shape
    out = np.empty((m, -(-n // step)))
    if n == 0 or m == 0:  # nothing to filter (the loop writes the first sample of every row)
        return out
    x = np.asarray(u, dtype=np.float64)
    if m < 4:  # the loop takes four rows at a time: padded with rows of zeros (rows do not mix)
        x = np.vstack([x, np.zeros((4 - m, n))])
        padded = np.empty((4, out.shape[1]))
        _first_order_rows_compiled(x, float(a), float(b0), float(b1), int(step), padded)
        out[:] = padded[:m]
        return out
    _first_order_rows_compiled(x, float(a), float(b0), float(b1), int(step), out)
    return out


_first_order_rows_compiled: Any = None


def _first_order_rows(u: Array, a: float, b0: float, b1: float, step: int, out: Array) -> None:
    # Four rows at a time (at least four rows; the caller pads fewer): a row's recursion is a
    # chain of dependent multiply-adds, and four chains in flight run 2.2x faster than one
    # (0.36 -> 0.16 ms on 15 rows of 13 000), each row's operations those of a one-row loop. Rows
    # left over by the fours go again with the three before them (the same values written twice).
    # The kept samples are counted, not found by ``i % step``: an integer division a sample cost
    # a third of the loop.
    m, n = u.shape
    a1 = -a
    r = 0
    while r < m:
        r = min(r, m - 4)
        p0 = p1 = p2 = p3 = 0.0  # from rest
        for q in range(4):
            out[r + q, 0] = 0.0
        c = 0
        k = 0
        for i in range(1, n):
            v0 = b1 * u[r, i]
            v0 += b0 * u[r, i - 1]
            p0 = v0 - a1 * p0
            v1 = b1 * u[r + 1, i]
            v1 += b0 * u[r + 1, i - 1]
            p1 = v1 - a1 * p1
            v2 = b1 * u[r + 2, i]
            v2 += b0 * u[r + 2, i - 1]
            p2 = v2 - a1 * p2
            v3 = b1 * u[r + 3, i]
            v3 += b0 * u[r + 3, i - 1]
            p3 = v3 - a1 * p3
            c += 1
            if c == step:
                c = 0
                k += 1
                out[r, k] = p0
                out[r + 1, k] = p1
                out[r + 2, k] = p2
                out[r + 3, k] = p3
        r += 4
