"""phid_ros.optimize (stage 1's envelope fit) against scipy.optimize.curve_fit at tight tolerances."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import curve_fit

from phid_ros.optimize import decay_fit


def test_decay_fit_reaches_the_least_squares_optimum():
    rng = np.random.default_rng(4)
    for _ in range(6):
        t = np.sort(rng.uniform(0, 10, 9))
        t -= t[0]
        y = 2.0 * np.exp(-0.3 * t) * (1 + 0.05 * rng.standard_normal(t.size))

        def env(tt, a0, alpha):
            return a0 * np.exp(-alpha * tt)

        tight, _ = curve_fit(env, t, y, p0=(y[0], 0.5), method="lm", maxfev=50_000, ftol=1e-15, xtol=1e-15, gtol=0)
        got = decay_fit(t, y, float(y[0]), 0.5)
        assert np.allclose(got, tight, rtol=1e-8, atol=0)


def test_decay_fit_on_exact_data_and_its_failure():
    t = np.linspace(0, 4, 9)
    a0, alpha = decay_fit(t, 3.0 * np.exp(-0.7 * t), 1.0, 0.1)
    assert a0 == pytest.approx(3.0, rel=1e-12) and alpha == pytest.approx(0.7, rel=1e-12)
    with pytest.raises(ValueError, match="decay_fit"):
        decay_fit(t, np.full(t.size, np.nan), 1.0, 0.5)
