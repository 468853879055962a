"""The numerical building blocks against their textbook references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import bilinear

from phid_ros.numerics import lowpass2_coefficients


@pytest.mark.parametrize("fc, dt", [(2.0, 1e-3), (10.0, 1e-3), (0.5, 0.02), (45.0, 1e-4)])
@pytest.mark.parametrize("derivative", [False, True])
def test_lowpass_coefficients_are_scipys_bilinear_map(fc, dt, derivative):
    w = 2.0 * np.pi * fc
    b_ref, a_ref = bilinear([w * w, 0.0] if derivative else [w * w], [1.0, 2.0 * w, w * w], 1.0 / dt)
    b, a = lowpass2_coefficients(fc, dt, derivative)
    np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b, np.pad(b_ref, (len(b) - len(b_ref), 0)), rtol=1e-12, atol=1e-15)


RNG = np.random.default_rng(3)


def close(got, want):
    # rounding, amplified by poles near 1 (0.997 for 0.5 Hz at 1 kHz): the direct form and
    # the cascade of first-order passes differ by some 1e-10 of the signal, both rounding
    scale = float(np.max(np.abs(want)))
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-9 * scale)


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("shape, axis", [((5000,), -1), ((3, 4000), 1), ((4000, 3), 0)])
def test_filters_equal_scipy_lfilter(shape, axis, compiled, monkeypatch):
    if not compiled:
        monkeypatch.setenv("PHID_NO_JIT", "1")  # LAPACK's banded triangular solve
    from scipy.signal import lfilter, lfilter_zi

    from phid_ros.numerics import first_order_response, lowpass2, lowpass2_derivative, recursive_first_order

    x = np.cumsum(RNG.standard_normal(shape), axis=axis) + 3.0
    dt = 1e-3
    for fc in (0.5, 2.0, 45.0):
        for derivative in (False, True):
            b, a = lowpass2_coefficients(fc, dt, derivative)
            want = lfilter(b, a, x, axis=axis)
            got = (lowpass2_derivative if derivative else lowpass2)(x, fc, dt, axis=axis)
            close(got, want)
        b, a = lowpass2_coefficients(fc, dt, False)
        x0 = np.take(x, [0], axis=axis)
        zi_shape = [1] * x.ndim
        zi_shape[axis] = 2
        want = lfilter(b, a, x, axis=axis, zi=lfilter_zi(b, a).reshape(zi_shape) * x0)[0]
        close(lowpass2(x, fc, dt, steady_start=True, axis=axis), want)
    for a1 in (0.5, 0.999):
        want = lfilter([1.0], [1.0, -a1], x, axis=axis)
        close(recursive_first_order(x, a1, axis=axis), want)
    tau = 0.13
    a1 = np.exp(-dt / tau)
    b0 = (tau - (tau + dt) * a1) / dt
    z = lfilter([1.0 - a1 - b0, b0], [1.0, -a1], x, axis=axis)
    n = x.shape[axis]
    shape_n = [1] * x.ndim
    shape_n[axis] = n
    want = z - np.take(z, [0], axis=axis) * (a1 ** np.arange(n)).reshape(shape_n)
    close(first_order_response(x, tau, dt, axis=axis), want)


@pytest.mark.parametrize("seed", range(6))
def test_find_peaks_equals_scipy(seed):
    from scipy.signal import find_peaks as scipy_find_peaks

    from phid_ros.numerics import find_peaks

    rng = np.random.default_rng(seed)
    x = np.abs(np.sin(np.linspace(0, 40, 3000)) + 0.3 * rng.standard_normal(3000))
    if seed % 2:
        x = np.round(x, 1)  # plateaus and equal heights
    for distance in (1, 2, 7, 100):
        want, _ = scipy_find_peaks(x, distance=distance)
        np.testing.assert_array_equal(find_peaks(x, distance=distance), want)


@pytest.mark.parametrize("a", [(-0.999,), (-1.9, 0.905), (-0.5, 0.1, -0.01)])
@pytest.mark.parametrize("shape, axis", [((3000,), -1), ((3000, 5), 0), ((4, 3000), 1), ((2, 3000, 3), 1)])
def test_compiled_recursion_equals_the_banded_solve(a, shape, axis, monkeypatch):
    from phid_ros.jit import available
    from phid_ros.numerics import all_pole

    if not available():
        pytest.skip("numba is not installed")
    x = RNG.standard_normal(shape)
    got = all_pole(x, a, axis=axis)
    monkeypatch.setenv("PHID_NO_JIT", "1")
    want = all_pole(x, a, axis=axis)
    assert got.shape == want.shape == x.shape
    # the same sums in the same order; OpenBLAS may fuse a multiply-add where the loop does not
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * float(np.max(np.abs(want))))


@pytest.mark.parametrize("rows", [1, 2, 4, 7, 15])
@pytest.mark.parametrize("step", [1, 5, 7])
def test_first_order_response_kept_is_the_full_response_decimated_bit_for_bit(rows, step, monkeypatch):
    """Stage 3's fused pass (input stage, recursion, decimation; four rows at a time) against the
    numpy input stage and the recursion over every sample, then one sample in ``step``."""
    from phid_ros.numerics import first_order_response, first_order_response_kept

    u = np.cumsum(RNG.standard_normal((rows, 4003)), axis=1)
    want = first_order_response(u, 0.37, 1e-3, axis=1)[:, ::step]
    got = first_order_response_kept(u, 0.37, 1e-3, step)
    np.testing.assert_array_equal(got, want)
    monkeypatch.setenv("PHID_NO_JIT", "1")
    np.testing.assert_allclose(first_order_response_kept(u, 0.37, 1e-3, step), want, rtol=1e-12, atol=1e-12)


def test_the_compiled_filters_take_read_only_integer_and_empty_input_as_numpy_does(monkeypatch):
    """Their explicit signatures must not refuse what the numpy path takes (a frozen window's view)."""
    from phid_ros.numerics import all_pole, first_order_response_kept

    x = np.arange(24.0).reshape(12, 2)
    x.setflags(write=False)
    ints = np.arange(24).reshape(2, 12)
    got = all_pole(x, (-0.5,), axis=0), first_order_response_kept(x.T, 0.1, 1e-3, 5)
    got_int = first_order_response_kept(ints, 0.1, 1e-3, 5)
    assert first_order_response_kept(np.zeros((3, 0)), 0.1, 1e-3, 5).shape == (3, 0)  # no sample: nothing written
    monkeypatch.setenv("PHID_NO_JIT", "1")
    np.testing.assert_allclose(got[0], all_pole(x, (-0.5,), axis=0), rtol=1e-12)
    np.testing.assert_allclose(got[1], first_order_response_kept(x.T, 0.1, 1e-3, 5), rtol=1e-12)
    np.testing.assert_allclose(got_int, first_order_response_kept(ints, 0.1, 1e-3, 5), rtol=1e-12)


@pytest.mark.parametrize("n", [0, 1, 2, 83, 4003])
def test_the_one_dimensional_first_order_response_is_the_column_s_bit_for_bit(n) -> None:
    """The control fits' fused 1-D pass against the numpy input stage and the recursion (the 2-D
    path, one column), on read-only and strided input too."""
    from phid_ros.numerics import first_order_response

    u = np.cumsum(RNG.standard_normal(2 * n))[::2]  # strided
    want = first_order_response(u.reshape(-1, 1), 0.37, 0.15, axis=0).ravel()
    np.testing.assert_array_equal(first_order_response(u, 0.37, 0.15), want)
    u.setflags(write=False)
    np.testing.assert_array_equal(first_order_response(u, 0.37, 0.15), want)
    ints = np.arange(n)
    np.testing.assert_array_equal(first_order_response(ints, 0.37, 0.15), first_order_response(1.0 * ints, 0.37, 0.15))
