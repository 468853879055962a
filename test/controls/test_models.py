"""The control models' declarations and their small-signal paths' steady states and lags."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from phid_ros.controls.models import MODELS, SEXS, TGOV1, ControlInputs, of_kind


def inputs(n: int = 20_000, dt: float = 1e-3, v_t: float = 0.0, speed: float = 0.0) -> ControlInputs:
    step = (np.arange(n) >= 1000).astype(float)
    return ControlInputs(dt, v_t * step, speed * step, step)


def test_every_model_declares_its_constants_in_range_and_is_registered_by_kind() -> None:
    assert {m.name for m in of_kind("exciter")} >= {"SEXS"} and {m.name for m in of_kind("governor")} >= {"TGOV1"}
    for model in MODELS.values():
        assert model.kind in ("exciter", "governor", "stabiliser") and model.description
        names = [p.name for p in model.parameters]
        assert len(names) == len(set(names)), model.name
        for p in model.parameters:
            assert p.low <= p.default <= p.high and not p.outside(p.default), (model.name, p.name)
        assert any(p.limit for p in model.parameters)  # every PSS/E record has its output limits


def test_sexs_settles_at_its_gain_and_starts_at_gain_times_ta_over_tb() -> None:
    v = {**SEXS().defaults(), "K": 50.0, "TA/TB": 0.2, "TB": 2.0, "TE": 0.05}
    e = SEXS().response(v, inputs(v_t=-0.01), 0.0)  # V_t 0.01 pu below the reference
    assert e[999] == 0.0 and e[-1] == pytest.approx(0.5, rel=1e-3)  # K * 0.01 after 19 s = 9.5 T_B
    # the lead-lag's step (0.2 of it at once, the rest with T_B) through T_E: two lags in a chain
    t, tb, te = 0.3, 2.0, 0.05
    chain = 1 - (tb * np.exp(-t / tb) - te * np.exp(-t / te)) / (tb - te)
    assert e[1000 + 300] == pytest.approx(0.5 * (0.2 * (1 - np.exp(-t / te)) + 0.8 * chain), rel=1e-3)
    # a reference step of 0.01 is the same as V_t falling by 0.01
    assert np.allclose(SEXS().response(v, inputs(), 0.01), e)


def test_tgov1_answers_a_speed_rise_with_minus_one_over_r_and_a_reference_step_fully() -> None:
    v = {**TGOV1().defaults(), "R": 0.05, "T1": 0.5, "T2": 1.0, "T3": 3.0, "Dt": 0.0}
    p = TGOV1().response(v, inputs(n=40_000, speed=0.001), 0.0)
    assert p[-1] == pytest.approx(-0.02, rel=1e-3)  # -dw/R after 39 s
    ref = TGOV1().response(v, inputs(n=40_000), 0.1)
    assert ref[-1] == pytest.approx(0.1, rel=1e-3)
    # the valve (T1) then the turbine's lead-lag: T2/T3 of the valve at once, the rest through T3
    t, t1, t3 = 2.5, 0.5, 3.0
    valve = 1 - np.exp(-t / t1)
    chain = 1 - (t3 * np.exp(-t / t3) - t1 * np.exp(-t / t1)) / (t3 - t1)
    assert ref[1000 + 2500] == pytest.approx(0.1 * (valve / 3 + 2 / 3 * chain), rel=1e-3)


EXCITER_GAIN = {"SEXS": lambda v: v["K"], "EXST1": lambda v: v["KA"], "IEEET1": lambda v: v["KA"] / v["KE"]}
EXCITER_GAIN["ESST5B"] = lambda v: v["KR"]
GOVERNOR_GAIN = {"TGOV1": lambda v: 1 / v["R"], "IEEEG1": lambda v: v["K"], "HYGOV": lambda v: v["At"] / v["R"]}


@pytest.mark.parametrize("name", sorted(m for m in MODELS if MODELS[m].kind != "stabiliser"))
def test_every_model_settles_at_its_steady_state_gain_and_follows_its_reference_fully(name: str) -> None:
    """A voltage 0.01 pu below the reference: E_fd settles at the regulator's gain times 0.01; a
    speed 0.001 pu high: P_m at -gain * 0.001 (1/R, K, A_t/R); a load-reference step of 0.1 pu
    moves P_m by 0.1 (the closed loops and the hydro turbine's linearisation included)."""
    model = MODELS[name]
    v = model.completed(model.defaults())
    long = dict(n=60_000, dt=0.01)  # 600 s: past a hydro governor's 55 s closed-loop pole
    if model.kind == "exciter":
        e = model.response(v, inputs(**long, v_t=-0.01), 0.0)
        assert e[-1] == pytest.approx(0.01 * EXCITER_GAIN[name](v), rel=1e-3)
        assert np.allclose(model.response(v, inputs(**long), 0.01), e)
        return
    x = replace(inputs(**long, speed=0.001), p_m0=0.8)
    assert model.response(v, x, 0.0)[-1] == pytest.approx(-0.001 * GOVERNOR_GAIN[name](v), rel=1e-3)
    assert model.response(v, replace(inputs(**long), p_m0=0.8), 0.1)[-1] == pytest.approx(0.1, rel=1e-3)


def test_ieeeg1_simulates_every_stage_a_record_gives() -> None:
    """``phid validate`` of an IEEEG1 record dropped T1, T2, T6, T7, K5, K7 and reset K3 to 1 - K1,
    and so checked another governor. Every stage of this shaft is now simulated: the response to a
    speed step is the record's whole transfer function (scipy's, not ours), and the shares as written."""
    from scipy.signal import lsim

    from phid_ros.controls.models import IEEEG1
    from phid_ros.controls.unit_validation import control_of

    v = {**IEEEG1().defaults(), "K": 20.0, "T1": 0.2, "T2": 1.0, "T3": 0.1, "T4": 0.3, "T5": 5.0, "T6": 0.5, "T7": 2.0}
    v.update({"K1": 0.3, "K3": 0.4, "K5": 0.2, "K7": 0.1})
    assert control_of("IEEEG1", v).values["K3"] == 0.4  # as written, not 1 - K1
    x = inputs(n=30_000, speed=0.001)
    p = IEEEG1().response(v, x, 0.0)
    t = np.arange(len(x.speed)) * x.dt
    s = np.polynomial.Polynomial([0.0, 1.0])
    lag = {k: 1 + v[k] * s for k in ("T3", "T4", "T5", "T6", "T7")}
    den = (1 + v["T1"] * s) * lag["T3"] * lag["T4"] * lag["T5"] * lag["T6"] * lag["T7"]
    stages = (
        v["K1"] * lag["T5"] * lag["T6"] * lag["T7"]
        + v["K3"] * lag["T6"] * lag["T7"]
        + v["K5"] * lag["T7"]
        + v["K7"] * 1
    )
    num = -v["K"] * (1 + v["T2"] * s) * stages
    _, want, _ = lsim((num.coef[::-1], den.coef[::-1]), x.speed, t)
    assert np.max(np.abs(p - want)) < 1e-3 * np.max(np.abs(want)), float(np.max(np.abs(p - want)))
    assert p[-1] == pytest.approx(-v["K"] * 0.001, rel=5e-3)  # all four shares, after 29 s (T5 5 s)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ({"K2": 0.2}, r"a second shaft's shares \(K2 = 0\.2\) drive another machine"),
        ({"T1": 0.0, "T2": 1.0}, r"T2 = 1 s with T1 = 0"),
        # a held time constant negative: refused where the model declares its constants (record_problem)
        ({"T6": -0.5}, r"T6 = -0\.5 is a negative time constant"),
    ],
)
def test_an_ieeeg1_record_phid_cannot_simulate_is_refused_by_name(tmp_path, edit, message) -> None:
    from phid_ros.export.dyr_read import DyrError, read_unit

    values = {"K": 20.0, "T1": 0.2, "T2": 0.0, "T3": 0.1, "UO": 1.0, "UC": -1.0, "PMAX": 1.0, "PMIN": 0.0}
    values.update({"T4": 0.3, "K1": 0.3, "K2": 0.0, "T5": 7.0, "K3": 0.7, "K4": 0.0, "T6": 0.0, "K5": 0.0})
    values.update({"K6": 0.0, "T7": 0.0, "K7": 0.0, "K8": 0.0, **edit})
    path = tmp_path / "unit.dyr"
    path.write_text(
        "1 'GENSAL' 1 5.0 0.05 0.05 3.0 0.0 1.1 0.7 0.3 0.22 0.15 0.0 0.0 /\n"
        "1 'IEEEG1' 1 0 0 " + " ".join(f"{x:g}" for x in values.values()) + " /\n"
    )
    with pytest.raises(DyrError, match=rf"unit\.dyr:2: IEEEG1:? {message}"):
        read_unit(path)


def _st5b(**over: float) -> dict[str, float]:
    from phid_ros.controls.models import ESST5B

    return {
        **ESST5B().defaults(),
        "TR": 0.01,
        "KR": 200.0,
        "T1": 0.005,
        "KC": 0.2,
        "VRMAX": 3.0,
        "VRMIN": -2.0,
        "TC1": 1.0,
        "TB1": 5.0,
        "TC2": 0.05,
        "TB2": 0.05,
        **over,
    }


def test_esst5b_limited_is_the_small_signal_path_away_from_its_limits() -> None:
    from phid_ros.controls.models import ESST5B, ControlInputs, OperatingLevels

    dt, n = 0.005, 2000
    step = (np.arange(n) >= 200).astype(float)
    x = ControlInputs(dt, 0.001 * np.sin(np.arange(n) * dt * 3), np.zeros(n), step)
    levels = OperatingLevels(np.ones(n), 1.2, 1.2)
    values = _st5b()
    linear = ESST5B().response(values, x, 0.001)
    limited = ESST5B().limited(values, x, 0.001, levels)
    assert limited is not None and np.max(np.abs(limited - linear)) < 1e-9


def test_esst5b_ceiling_follows_v_t_and_the_rectifier_loading_and_lets_go_at_once() -> None:
    """A +5 % reference step for 1 s: V_R far above VRMAX; E_fd sits at VRMAX V_T - K_C I_FD and
    leaves it as soon as the step is taken back (non-windup: no integrator to unwind)."""
    from phid_ros.controls.models import ESST5B, ControlInputs, LimitsError, OperatingLevels

    dt, n = 0.005, 800
    t = np.arange(n) * dt
    step = ((t >= 0.5) & (t < 1.5)).astype(float)
    v_t = 1.0 - 0.05 * ((t >= 0.8) & (t < 1.2))  # the terminal voltage sags while at the ceiling
    x = ControlInputs(dt, np.zeros(n), np.zeros(n), step)
    values = _st5b()
    efd = 1.2 + ESST5B().limited(values, x, 0.05, OperatingLevels(v_t, 1.2, 1.2))
    ceiling = 3.0 * v_t - 0.2 * 1.2
    assert np.all(efd <= ceiling + 1e-12)
    on = (t > 0.6) & (t < 1.45) & ~((t >= 1.2) & (t < 1.25))  # but the T_1 lag rising after the sag
    assert np.allclose(efd[on], ceiling[on], atol=1e-4)  # K_R 200 x 0.05: held at the ceiling throughout
    assert efd[int(1.52 / dt)] < 0.5 * (efd[int(1.45 / dt)] + 1.2)  # down within 20 ms of the return
    with pytest.raises(LimitsError, match="V_R at rest 3.36"):
        ESST5B().limited(values, x, 0.05, OperatingLevels(v_t, 2.8, 2.8))


def test_ieeest_is_its_block_diagram_on_the_electrical_power() -> None:
    """K_S sT_5/(1 + sT_6) (1 + sT_1)/(1 + sT_2) (1 + sT_3)/(1 + sT_4) on a step of P_e is the
    whole transfer function as scipy simulates it (not ours); T_5 follows T_6; the two lead-lags,
    which commute, come in one order (a lag without lead first)."""
    from scipy.signal import lsim

    from phid_ros.controls.models import IEEEST

    v = IEEEST().completed({**IEEEST().defaults(), "T1": 0.3, "T2": 0.1, "T3": 0.0, "T4": 0.02, "T6": 2.0, "KS": -0.5})
    assert (v["T1"], v["T2"], v["T3"], v["T4"], v["T5"]) == (0.0, 0.02, 0.3, 0.1, 2.0)
    dt, n = 0.001, 20000
    p_e = 0.1 * (np.arange(n) >= 1000)
    x = ControlInputs(dt, np.zeros(n), np.zeros(n), np.zeros(n), p_e=p_e)
    y = IEEEST().response(v, x, 0.0)
    num = np.polymul(np.polymul([v["KS"] * v["T5"], 0.0], [v["T1"], 1.0]), [v["T3"], 1.0])
    den = np.polymul(np.polymul([v["T6"], 1.0], [v["T2"], 1.0]), [v["T4"], 1.0])
    _, ref, _ = lsim((num, den), p_e, np.arange(n) * dt)
    assert y[999] == 0.0 and np.max(np.abs(y - ref)) < 1e-3 * np.max(np.abs(ref))
    assert y[1050] < -0.05  # the lead: more than K_S x 0.1 at first, washed out after
    # without P_e recorded the model does not apply
    assert np.isnan(IEEEST().response(v, ControlInputs(dt, np.zeros(10), np.zeros(10), np.zeros(10)), 0.0)).all()


def test_a_non_windup_lead_lag_leaves_its_limit_where_the_input_allows_and_goes_no_further() -> None:
    """ESST5B's first lead-lag as the Mostar unit's published record has it (T_C1 1.701 s, T_B1
    21.98 s) behind a gain of 505: a reference step drives its input far past the ceiling for a few
    tens of ms, then back. The output sits on the ceiling, then returns to the linear answer of an
    input that came back: it never crosses to the floor (setting the state so that the output sat
    exactly on the ceiling drove it to -8.4 once the input fell back)."""
    from phid_ros.controls.models import lead_lag, nonwindup_lead_lag

    dt, t_c, t_b = 0.001, 1.701, 21.98
    n = 3000
    u = np.full(n, 2.2)
    u[1000:1040] = 2.2 + 505 * 0.1  # the forcing: 40 ms at 50 pu over rest
    y = nonwindup_lead_lag(u, t_c, t_b, dt, -8.384, 2.237, 2.2)
    assert np.all(y >= 2.2 - 1e-9) and np.all(y <= 2.237 + 1e-12)
    assert np.all(y[1000:1040] == 2.237)
    # after the forcing the state has not moved beyond where it was: the output is back at rest
    assert y[-1] == pytest.approx(2.2, abs=2e-3)
    # never limited: the linear lead-lag
    small = np.full(n, 1.0)
    small[500:] = 1.1
    free = nonwindup_lead_lag(small, t_c, t_b, dt, -8.384, 2.237, 1.0)
    assert np.allclose(free, 1.0 + lead_lag(small - 1.0, t_c, t_b, dt), atol=1e-12)


def test_the_compiled_non_windup_lead_lag_is_the_python_loop_bit_for_bit() -> None:
    """The loop compiled (numba) gives the numbers of the same loop run as Python, limits hit
    both ways, a lead above and below its lag (1 - r of either sign)."""
    from phid_ros.controls.models.blocks import _nonwindup_lead_lag_loop

    python_loop = getattr(_nonwindup_lead_lag_loop, "py_func", None)
    if python_loop is None:
        pytest.skip("numba is not importable: there is no compiled loop to compare")
    rng = np.random.default_rng(3)
    u = 6.0 * np.sin(np.arange(4000) / 300.0) + rng.normal(0.0, 0.3, 4000)
    reached = set()
    for r in (0.077, 1.0, 4.2):
        args = (u, r, 0.999, 0.0005, 0.0005, -2.0, 1.5, 0.1)
        y = python_loop(*args)
        assert np.array_equal(_nonwindup_lead_lag_loop(*args), y)
        reached |= {float(v) for v in (y.max(), y.min()) if v in (1.5, -2.0)}
    assert reached == {1.5, -2.0}


def test_a_model_with_a_constant_held_is_another_value_of_its_class_and_leaves_the_registry_alone() -> None:
    from phid_ros.controls.choice import _holding

    exst1 = MODELS["EXST1"]
    held = _holding(exst1, "KF")
    assert type(held) is type(exst1) and held is not exst1
    kf, tf = (next(p for p in held.parameters if p.name == n) for n in ("KF", "TF"))
    assert kf.held and kf.default == kf.low == kf.high == 0.0 and tf.held  # T_F is moot without K_F
    assert not any(p.held for p in MODELS["EXST1"].parameters if p.name in ("KF", "TF"))
    assert len(held.fitted()) == len(exst1.fitted()) - 2 and repr(held) == "EXST1(held=['KF', 'TF'])"
    # the same equations: with K_F at 0 the held model and the free one answer alike
    v = {**exst1.defaults(), "KF": 0.0}
    x = inputs(v_t=-0.01)
    assert np.array_equal(held.response(v, x, 0.0), exst1.response(v, x, 0.0))


def test_a_stabiliser_through_an_exciter_answers_as_the_exciter_driven_by_its_output() -> None:
    from phid_ros.controls.stabiliser_effect import ThroughExciter

    sexs, pss = MODELS["SEXS"], MODELS["IEEEST"]
    exciter = {**sexs.defaults(), "K": 50.0, "TA/TB": 0.2, "TB": 2.0, "TE": 0.05}
    stabiliser = pss.completed({**pss.defaults(), "T1": 0.3, "T2": 0.1, "T4": 0.02, "KS": -0.5})
    n, dt = 5000, 1e-3
    step = (np.arange(n) >= 1000).astype(float)
    x = ControlInputs(dt, np.zeros(n), np.zeros(n), np.zeros(n), p_e=0.05 * step)
    through = ThroughExciter(pss, sexs, exciter)
    assert through.name == "IEEEST" and through.kind == "stabiliser" and through.parameters == pss.parameters
    v_s = pss.response(stabiliser, x, 0.0)
    assert np.abs(v_s).max() > 1e-3  # the stabiliser answers the power step
    expected = sexs.response(exciter, replace(x, v_s=v_s), 0.0)
    assert np.array_equal(through.response(stabiliser, x, 0.0), expected)
    assert through.start({}) == pss.start({}) and through.completed(stabiliser) == pss.completed(stabiliser)


def test_a_nesting_model_starts_where_the_simpler_one_ended() -> None:
    sexs = {**MODELS["SEXS"].defaults(), "K": 80.0, "TA/TB": 0.25, "TB": 4.0, "TE": 0.04}
    exst1 = MODELS["EXST1"].start({"SEXS": sexs})
    assert exst1["TC"] == pytest.approx(1.0) and exst1["TB"] == 4.0 and exst1["KA"] == 80.0 and exst1["TA"] == 0.04
    esst5b = MODELS["ESST5B"].start({"SEXS": sexs})
    assert esst5b["TC1"] == pytest.approx(1.0) and esst5b["KR"] == 80.0 and esst5b["T1"] == 0.04
    assert MODELS["EXST1"].start({}) == MODELS["EXST1"].defaults()
    pss2b = MODELS["PSS2B"].start({"PSS2A": {**MODELS["PSS2A"].defaults(), "KS1": 17.0}})
    assert pss2b["KS1"] == 17.0 and pss2b["T10"] == pss2b["T11"] == 0.1


def test_every_datum_a_model_declares_is_one_a_model_seen_through_another_carries() -> None:
    from phid_ros.controls.models import MODEL_DATA, ControlModel

    declared = set(ControlModel.__annotations__)
    assert declared == set(MODEL_DATA), declared ^ set(MODEL_DATA)
