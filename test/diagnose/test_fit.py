"""The output-error fit: profile starts, flat valleys, starts the play-in rejects."""

from __future__ import annotations

import numpy as np


def test_a_profile_point_starts_where_the_final_fit_s_jacobian_predicts():
    # X'_d and T'_d0 trade off along a valley: residual ~ 1 * dx(X'_d) + 2 * dx(T'_d0). Holding X'_d
    # 10 % higher, the best T'_d0 moves by half that step the other way (log coordinates).
    import math
    from types import SimpleNamespace

    from phid_ros.diagnose.candidates import FreeParameter
    from phid_ros.diagnose.determinability import profile_start
    from phid_ros.diagnose.fit import FitResult, ModelSpec

    xd, td = FreeParameter("X_d_prime", 0.1, 1.0, log=True), FreeParameter("T_d0_prime", 0.5, 5.0, log=True)
    x = np.log([0.5, 1.4])
    jac = np.array([[0.0, 0.0], [1.0, 2.0], [0.0, 0.0]])
    spec = ModelSpec({"X_d_prime": 0.5, "T_d0_prime": 1.4})
    final = FitResult(spec, 1.0, 10, 2, x=x, free=((-1, xd), (-1, td)), jac=jac)
    start = profile_start(final, SimpleNamespace(free=[(-1, td)]), "X_d_prime", 1.1)
    assert start is not None and np.allclose(start, [math.log(1.4) - math.log(1.1) / 2], rtol=0, atol=1e-12)
    # without the final fit's Jacobian (an older result) the refit starts from the final values
    assert profile_start(FitResult(final.model, 1.0, 10, 2), SimpleNamespace(free=[(-1, td)]), "X_d_prime", 1.1) is None


def test_an_effect_parameter_that_rides_a_flat_valley_is_not_determined() -> None:
    """The numbers of ANDES's GENROU with close q-axis time constants (genrou-sub-fast): in the
    refits the held-out data could not tell from the best, X''_q moved 2 % (its std 0.15 %) and
    T''_q0 18 %; X''_d and T''_d0 stayed within 0.4 %."""
    from phid_ros.diagnose.candidates import SaturationCandidate, SubtransientCandidate
    from phid_ros.diagnose.determinability import effects_determined
    from phid_ros.diagnose.fit import FitResult, ModelSpec

    final = {"x_dpp": 0.2621, "x_qpp": 0.2787, "t_d0pp": 0.0319, "t_q0pp": 0.0355}
    std = {"x_dpp": 0.00028, "x_qpp": 0.00042, "t_d0pp": 0.00008, "t_q0pp": 0.00039}
    sat = {"s10": 0.07, "s12": 0.45, "form": "genrou", "curve": "quadratic"}
    spec = ModelSpec({}, [(SubtransientCandidate, final), (SaturationCandidate, sat)])
    res = FitResult(spec, 1.0, 10, 4, 1, "", [std, {"s10": 0.001, "s12": 0.002}], {})
    sub = ({"x_dpp": 0.2626, "x_qpp": 0.2762, "t_d0pp": 0.0320, "t_q0pp": 0.0291},
           {"x_dpp": 0.2617, "x_qpp": 0.2815, "t_d0pp": 0.0319, "t_q0pp": 0.0421})  # fmt: skip
    sats = ({"s10": 0.0701, "s12": 0.4502}, {"s10": 0.0699, "s12": 0.4499})
    alike = [{"subtransient_dynamics": a, "magnetic_saturation": b} for a, b in zip(sub, sats)]
    flags, notes = effects_determined(res, alike)
    assert flags["subtransient_dynamics"] == {"x_dpp": True, "x_qpp": False, "t_d0pp": True, "t_q0pp": False}
    assert flags["magnetic_saturation"] == {"s10": True, "s12": True}  # form and curve are chosen, not estimated
    assert len(notes) == 2 and "x_qpp = 0.2787 not determined" in notes[0] and "0.2762-0.2815" in notes[0]
    # no refit alike the best (every base parameter determined): every effect parameter stands
    assert all(all(f.values()) for f in effects_determined(res, [])[0].values())


def test_a_start_the_play_in_rejects_is_moved_back_not_a_crash() -> None:
    """A profile point's predicted start where the play-in diverged stopped the whole diagnosis
    ("Residuals are not finite in the initial point", a GENSAL machine with saturation and
    dampers). The start steps back toward the model's own values until the residuals are finite."""
    import pytest

    from phid_ros.diagnose.fit import FitError, finite_start

    def residual(x: np.ndarray) -> np.ndarray:  # the model diverges beyond x = 2
        return np.where(x < 2.0, x - 1.0, np.nan)

    got = finite_start(residual, np.array([9.0]), np.array([1.0]))
    assert 1.0 < got[0] < 2.0  # 9 -> 5 -> 3 -> 2 -> 1.5: the first finite point on the way back
    assert np.array_equal(finite_start(residual, np.array([1.5]), np.array([1.0])), [1.5])  # a good start stays
    with pytest.raises(FitError, match="diverges at the start and on the way back"):
        finite_start(lambda x: np.full(3, np.nan), np.array([9.0]), np.array([1.0]))
    # residuals each finite whose square sum is not (STEPS's saturated GENSAL: 1e160 and more)
    huge = finite_start(lambda x: np.where(x < 2.0, x - 1.0, 1e200) * np.ones(3), np.array([9.0]), np.array([1.0]))
    assert 1.0 < huge[0] < 2.0


def test_a_predicted_start_the_data_like_less_than_the_model_s_own_is_not_taken() -> None:
    """A profile point's first-order start moved a saturated GENSAL's flat directions far enough
    that the refit lost itself (H, 0.03 % from the machine's, then reported not determined); a
    start is kept only where its square sum is no worse than at the model's own values."""
    from phid_ros.diagnose.fit import chosen_start

    def residual(x: np.ndarray) -> np.ndarray:  # best at x = 1, diverging beyond 4
        return np.where(x < 4.0, (x - 1.0) * np.ones(3), np.nan)

    own = np.array([2.0])
    assert np.array_equal(chosen_start(residual, np.array([1.2]), own), [1.2])  # better: taken
    assert np.array_equal(chosen_start(residual, np.array([-3.0]), own), [2.0])  # worse: the own values
    # beyond the divergence it steps back (9 -> 5.5 -> 3.75) and then compares: 3.75 is worse than 2
    assert np.array_equal(chosen_start(residual, np.array([9.0]), own), [2.0])
    assert np.array_equal(chosen_start(residual, None, own), [2.0])
