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
