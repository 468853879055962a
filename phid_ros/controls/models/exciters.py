"""Excitation systems as PSS/E defines them (output E_fd): SEXS, EXST1, IEEET1, ESST5B."""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache

import numpy as np

from phid_ros.controls.models.base import (
    TRANSDUCER,
    ControlModel,
    ControlParameter,
    LimitsError,
    OperatingLevels,
    register,
)
from phid_ros.controls.models.blocks import (
    Array,
    ControlInputs,
    _lead_lag_steps,
    first_order,
    lag,
    lead_lag,
    nonwindup_lag,
    nonwindup_lead_lag,
    regulator_error,
    transfer,
)
from phid_ros.jit import jit_on_first_call


# The transfer functions' polynomials, cached on their constants: a fit plays every case with the
# same constants, and numpy's polymul (poly1d, trim_zeros) took a quarter of the exciter search
# on 30 polled steps; the same operations, so the same coefficients.
@lru_cache(maxsize=256)
def _exst1_transfer(
    ta: float, tb: float, tc: float, tf: float, ka: float, kf: float
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    # E/e = K_A (1 + sT_C)(1 + sT_F) / [(1 + sT_A)(1 + sT_B)(1 + sT_F) + K_A K_F s (1 + sT_C)]
    loop = np.polymul(np.polymul(first_order(ta), first_order(tb)), first_order(tf))
    den = np.polyadd(loop, ka * kf * np.polymul([1.0, 0.0], first_order(tc)))
    num = ka * np.polymul(first_order(tc), first_order(tf))
    return tuple(map(float, num)), tuple(map(float, den))  # a cached value, never an array to change


@lru_cache(maxsize=256)
def _ieeet1_transfer(
    ta: float, te: float, ke: float, tf: float, ka: float, kf: float
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    # E/e = K_A (1 + sT_F) / [(1 + sT_A)(K_E + sT_E)(1 + sT_F) + K_A K_F s]
    loop = np.polymul(np.polymul(first_order(ta), [te, ke]), first_order(tf))
    den = np.polyadd(loop, [ka * kf, 0.0])
    num = ka * first_order(tf)
    return tuple(map(float, num)), tuple(map(float, den))


def _sexs_as(sexs: Mapping[str, float], lead: str, lag: str, gain: str, field: str) -> dict[str, float]:
    """A SEXS fit as the constants of a static exciter that nests it (EXST1, ESST5B): its lead-lag
    T_A/T_B, T_B, gain K and field lag T_E under the larger model's names, a transducer of no lag."""
    return {lead: sexs["TA/TB"] * sexs["TB"], lag: sexs["TB"], gain: sexs["K"], field: sexs["TE"], "TR": 1e-3}


@register
class SEXS(ControlModel):
    """Simplified excitation system: (V_ref - V_t) through (1 + sT_A)/(1 + sT_B), K/(1 + sT_E)."""

    name = "SEXS"
    kind = "exciter"
    description = "simplified excitation system (PSS/E SEXS)"
    in_andes = True
    andes_names = {"TA/TB": "TATB"}
    parameters = (
        ControlParameter("TA/TB", "", 0.1, 0.01, 1.0, "lead-lag ratio T_A/T_B"),
        ControlParameter("TB", "s", 10.0, 0.1, 30.0, "lag time constant T_B"),
        ControlParameter("K", "pu", 100.0, 5.0, 1000.0, "steady-state gain"),
        ControlParameter("TE", "s", 0.05, 0.002, 2.0, "exciter time constant T_E"),
        ControlParameter("EMIN", "pu", -5.0, -20.0, 0.0, "minimum field voltage", limit=True),
        ControlParameter("EMAX", "pu", 5.0, 1.0, 20.0, "maximum field voltage", limit=True),
    )

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        tb = values["TB"]
        e = regulator_error(x, reference, x.v_t)
        return values["K"] * lag(lead_lag(e, values["TA/TB"] * tb, tb, x.dt), values["TE"], x.dt)

    simulated_limits = ("EMIN", "EMAX")
    simulated_limits_how = "E_fd within EMIN..EMAX on a non-windup T_E lag (PSS/E SEXS)"
    output_limits = ("EMIN", "EMAX")

    def limited(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        v = values
        if not v["EMIN"] <= levels.output0 <= v["EMAX"]:
            raise LimitsError(
                f"E_fd at rest {levels.output0:.3f} lies outside EMIN..EMAX {v['EMIN']:g}..{v['EMAX']:g}: the "
                "limits do not hold the recorded operating point"
            )
        tb = v["TB"]
        e = regulator_error(x, reference, x.v_t)
        u = levels.output0 + v["K"] * lead_lag(e, v["TA/TB"] * tb, tb, x.dt)
        lo, hi = np.full(len(u), v["EMIN"]), np.full(len(u), v["EMAX"])
        return nonwindup_lag(u, v["TE"], x.dt, lo, hi, levels.output0) - levels.output0


@register
class EXST1(ControlModel):
    """Static (bus-fed) excitation system, IEEE ST1A-like: V_t sensed through 1/(1 + sT_R), the error
    through (1 + sT_C)/(1 + sT_B) and K_A/(1 + sT_A), a rate feedback sK_F/(1 + sT_F) of the output."""

    name = "EXST1"
    kind = "exciter"
    description = "static excitation system, IEEE ST1A-like (PSS/E EXST1)"
    in_andes = True
    parameters = (
        TRANSDUCER,
        ControlParameter("VIMAX", "pu", 0.2, 0.0, 1.0, "maximum error signal", limit=True),
        ControlParameter("VIMIN", "pu", -0.2, -1.0, 0.0, "minimum error signal", limit=True),
        ControlParameter("TC", "s", 1.0, 0.01, 20.0, "lead time constant T_C"),
        ControlParameter("TB", "s", 10.0, 0.05, 30.0, "lag time constant T_B"),
        ControlParameter("KA", "pu", 200.0, 5.0, 1000.0, "regulator gain"),
        ControlParameter("TA", "s", 0.02, 0.002, 1.0, "regulator time constant"),
        ControlParameter("VRMAX", "pu", 5.0, 1.0, 20.0, "maximum regulator output", limit=True),
        ControlParameter("VRMIN", "pu", -5.0, -20.0, 0.0, "minimum regulator output", limit=True),
        ControlParameter("KC", "pu", 0.0, 0.0, 1.0, "rectifier loading factor (enters the limits only)", limit=True),
        ControlParameter("KF", "pu", 0.0, 0.0, 1.0, "rate feedback gain", absent=0.0),
        ControlParameter("TF", "s", 1.0, 0.05, 20.0, "rate feedback time constant", within="KF"),
    )

    def start(self, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        # SEXS is EXST1 without its transducer and rate feedback
        return self.started_from(earlier, "SEXS", lambda s: {**_sexs_as(s, "TC", "TB", "KA", "TA"), "KF": 1e-3})

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        sensed = lag(x.v_t, v["TR"], x.dt)
        num, den = _exst1_transfer(v["TA"], v["TB"], v["TC"], v["TF"], v["KA"], v["KF"])
        return transfer(regulator_error(x, reference, sensed), num, den, x.dt)

    simulated_limits = ("VIMAX", "VIMIN", "VRMAX", "VRMIN", "KC")
    output_limits = ("VRMIN", "VRMAX")
    input_limits = ("VIMIN", "VIMAX")
    loading = "KC"
    simulated_limits_how = (
        "the error within VIMIN..VIMAX, E_fd within VRMIN V_T..VRMAX V_T - K_C I_FD on the regulator's "
        "output (PSS/E EXST1; the lag winds up), the rate feedback inside the input limiter; I_FD held at "
        "its pre-event value"
    )

    def limit_at(self, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        # E_fd's ceiling is V_T VRMAX - K_C I_FD (floor V_T VRMIN): with K_C not reached, V_T's share
        return output / float(levels.v_t[k]) if name in ("VRMAX", "VRMIN") else output

    def limited(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return self._played(values, x, reference, levels, limited=True)[0] - levels.output0

    def input_signal(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return self._played(values, x, reference, levels, limited=False)[1]

    def _played(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels, *, limited: bool
    ) -> tuple[Array, Array]:
        """E_fd and the error at the input limiter, sample by sample (the rate feedback closes a
        loop around the limiter, so no filter chain gives it); ``limited`` False: every limit open."""
        v = values
        vi0 = levels.output0 / v["KA"]  # at rest the lead-lag passes the error at gain 1, K_A makes E_fd
        loading = v["KC"] * levels.i_fd0
        n = len(x.v_t)
        if limited:
            if not v["VIMIN"] <= vi0 <= v["VIMAX"]:
                raise LimitsError(
                    f"the error at rest {vi0:.4f} (E_fd {levels.output0:.3f} / K_A {v['KA']:g}) lies outside "
                    f"VIMIN..VIMAX {v['VIMIN']:g}..{v['VIMAX']:g}: the limits do not hold the recorded operating point"
                )
            lo, hi = v["VRMIN"] * levels.v_t, v["VRMAX"] * levels.v_t - loading
            if not lo[0] <= levels.output0 <= hi[0]:
                raise LimitsError(
                    f"E_fd at rest {levels.output0:.3f} lies outside V_T VRMIN..V_T VRMAX - K_C I_FD "
                    f"{lo[0]:.3f}..{hi[0]:.3f}: the record's limits do not hold the recorded operating point"
                )
            in_lo, in_hi = v["VIMIN"], v["VIMAX"]
        else:
            lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
            in_lo, in_hi = -np.inf, np.inf
        external = regulator_error(x, reference, lag(x.v_t, v["TR"], x.dt))
        out = _exst1_loop(
            np.ascontiguousarray(external, np.float64),
            float(vi0),
            float(in_lo),
            float(in_hi),
            *_lead_lag_steps(v["TC"], v["TB"], x.dt),
            float(v["KA"]),
            *_lead_lag_steps(0.0, v["TA"], x.dt)[1:],
            float(v["KF"] / v["TF"]) if v["TF"] > 1e-6 else 0.0,
            *_lead_lag_steps(0.0, v["TF"], x.dt)[1:],
            np.ascontiguousarray(lo, np.float64),
            np.ascontiguousarray(hi, np.float64),
        )
        return out[0], out[1]


def _exst1_steps(
    external: Array,
    vi0: float,
    in_lo: float,
    in_hi: float,
    r: float,
    a_ll: float,
    b0_ll: float,
    b1_ll: float,
    ka: float,
    a_a: float,
    b0_a: float,
    b1_a: float,
    g_f: float,
    a_f: float,
    b0_f: float,
    b1_f: float,
    lo: Array,
    hi: Array,
) -> Array:
    # each step solved with the rate feedback of the same instant (implicit: an explicit one-step
    # delay in a loop of gain K_A K_F / T_F rings): the regulator's output is p + q x the limited
    # error, the feedback g (1 - b1_f) times it less w, so the unlimited error solves one linear
    # equation and the limiter clips that solution
    n = len(external)
    out = np.empty((2, n))
    x_ll, x_a, z = vi0, vi0, ka * vi0
    vl_prev, y_prev, vr_prev = vi0, vi0, ka * vi0
    q = ka * b1_a * (r + (1.0 - r) * b1_ll)
    gain = g_f * (1.0 - b1_f)
    for k in range(n):
        x_ll_next = a_ll * x_ll + b0_ll * vl_prev
        x_a_next = a_a * x_a + b0_a * y_prev
        p = ka * (x_a_next + b1_a * (1.0 - r) * x_ll_next)
        w = g_f * (a_f * z + b0_f * vr_prev)
        base = vi0 + external[k] + w
        vi = (base - gain * p) / (1.0 + gain * q)
        vl = min(max(vi, in_lo), in_hi)
        if vl != vi:
            vi = base - gain * (p + q * vl)
        x_ll = x_ll_next + b1_ll * vl
        y = r * vl + (1.0 - r) * x_ll
        x_a = x_a_next + b1_a * y
        vr = ka * x_a
        z = a_f * z + b0_f * vr_prev + b1_f * vr
        out[0, k] = min(max(vr, lo[k]), hi[k])
        out[1, k] = vi
        vl_prev, y_prev, vr_prev = vl, y, vr
    return out


_exst1_loop = jit_on_first_call(_exst1_steps)


@register
class IEEET1(ControlModel):
    """DC commutator exciter (IEEE type 1, PSS/E IEEET1): K_A/(1 + sT_A) on the error less the rate
    feedback sK_F/(1 + sT_F) of E_fd, the exciter 1/(K_E + sT_E)."""

    name = "IEEET1"
    kind = "exciter"
    description = "DC commutator exciter, IEEE type 1 (PSS/E IEEET1)"
    in_andes = True
    andes_names = {"SWITCH": "Switch"}
    parameters = (
        TRANSDUCER,
        ControlParameter("KA", "pu", 50.0, 5.0, 1000.0, "regulator gain"),
        ControlParameter("TA", "s", 0.05, 0.002, 1.0, "regulator time constant"),
        ControlParameter("VRMAX", "pu", 5.0, 0.5, 20.0, "maximum regulator output", limit=True),
        ControlParameter("VRMIN", "pu", -5.0, -20.0, 0.0, "minimum regulator output", limit=True),
        # the small-signal response is unchanged when K_A, K_E and T_E scale together (and the
        # saturation's slope at the operating point adds to K_E): K_E is held at 1 (a separately
        # excited exciter's, PSS/E's usual); K_A and T_E are then K_A/K_E and T_E/K_E
        ControlParameter("KE", "pu", 1.0, 1.0, 1.0, "exciter constant (held at 1: see the class)", held=True),
        ControlParameter("TE", "s", 0.5, 0.02, 5.0, "exciter time constant"),
        ControlParameter("KF", "pu", 0.05, 0.0, 0.5, "rate feedback gain", absent=0.0),
        ControlParameter("TF", "s", 1.0, 0.05, 20.0, "rate feedback time constant", within="KF"),
        ControlParameter("SWITCH", "", 0.0, 0.0, 0.0, "PSS/E's unused switch", held=True),
        ControlParameter("E1", "pu", 0.0, 0.0, 0.0, "first saturation point", limit=True),
        ControlParameter("SE1", "", 0.0, 0.0, 0.0, "saturation at E1", limit=True),
        ControlParameter("E2", "pu", 0.0, 0.0, 0.0, "second saturation point", limit=True),
        ControlParameter("SE2", "", 0.0, 0.0, 0.0, "saturation at E2", limit=True),
    )

    def record_problem(self, values: Mapping[str, float]) -> str | None:
        if values["KE"] == 0.0:
            # PSS/E computes K_E at initialisation where the record gives 0; simulated as 0 the
            # exciter would be an integrator: a wrong model, not a validation
            return "KE = 0 (PSS/E computes it at initialisation so V_R starts at 0): give the unit's K_E"
        return super().record_problem(values)

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        sensed = lag(x.v_t, v["TR"], x.dt)
        num, den = _ieeet1_transfer(v["TA"], v["TE"], v["KE"], v["TF"], v["KA"], v["KF"])
        return transfer(regulator_error(x, reference, sensed), num, den, x.dt)


@register
class ESST5B(ControlModel):
    """Static exciter with two lead-lags, IEEE ST5B's voltage regulator path: (1 + sT_C1)/(1 + sT_B1),
    (1 + sT_C2)/(1 + sT_B2), K_R/(1 + sT_1). The over- and under-excitation limiters' lead-lags
    act only while a limiter does (never in a small-signal test): held with lead = lag.

    The record's order is the one PNNL's power plant model validation tool and InterPSS read an
    ESST5B in (T_R, K_R, T_1, K_C, V_RMAX, V_RMIN, T_C1, T_B1, T_C2, T_B2, then the limiters' T_OC1,
    T_OB1, T_OC2, T_OB2, T_UC1, T_UB1, T_UC2, T_UB2)."""

    outside_path = ("TOC1", "TOB1", "TOC2", "TOB2", "TUC1", "TUB1", "TUC2", "TUB2")

    name = "ESST5B"
    kind = "exciter"
    description = "static exciter with two lead-lags, IEEE ST5B (ESST5B)"
    parameters = (
        TRANSDUCER,
        ControlParameter("KR", "pu", 200.0, 5.0, 1000.0, "regulator gain"),
        ControlParameter("T1", "s", 0.004, 0.001, 1.0, "firing circuit time constant"),
        ControlParameter("KC", "pu", 0.0, 0.0, 1.0, "rectifier loading factor (enters the limits only)", limit=True),
        ControlParameter("VRMAX", "pu", 5.0, 1.0, 20.0, "maximum regulator output", limit=True),
        ControlParameter("VRMIN", "pu", -5.0, -20.0, 0.0, "minimum regulator output", limit=True),
        ControlParameter("TC1", "s", 1.0, 0.01, 20.0, "first lead time constant"),
        ControlParameter("TB1", "s", 10.0, 0.05, 30.0, "first lag time constant"),
        ControlParameter("TC2", "s", 0.1, 0.01, 20.0, "second lead time constant"),
        ControlParameter("TB2", "s", 0.1, 0.01, 30.0, "second lag time constant"),
        *(
            ControlParameter(n, "s", 1.0, 1.0, 1.0, "limiter lead-lag (acts only with its limiter)", held=True)
            for n in ("TOC1", "TOB1", "TOC2", "TOB2", "TUC1", "TUB1", "TUC2", "TUB2")
        ),
    )

    def start(self, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        # SEXS is ESST5B with its second lead-lag a wire
        return self.started_from(earlier, "SEXS", lambda s: _sexs_as(s, "TC1", "TB1", "KR", "T1"))

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        e = regulator_error(x, reference, lag(x.v_t, v["TR"], x.dt))
        first = lead_lag(e, v["TC1"], v["TB1"], x.dt)
        return v["KR"] * lag(lead_lag(first, v["TC2"], v["TB2"], x.dt), v["T1"], x.dt)

    def limit_at(self, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        # E_fd's bound is V_T VRMAX - K_C I_FD (V_T VRMIN): with K_C not reached, V_R's limit is E_fd / V_T
        return output / float(levels.v_t[k]) if name in ("VRMAX", "VRMIN") else output

    simulated_limits = ("KC", "VRMAX", "VRMIN")
    output_limits = ("VRMIN", "VRMAX")
    loading = "KC"
    simulated_limits_how = (
        "V_R within VRMIN..VRMAX after the lead-lags, E_fd within VRMIN V_T..VRMAX V_T - K_C I_FD on a "
        "non-windup T_1 lag, the first lead-lag non-windup (IEEE 421.5 ST5B); I_FD held at its pre-event value"
    )

    def limited(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        v = values
        loading = v["KC"] * levels.i_fd0
        v_r0 = levels.output0 + loading  # at rest V_R = E_fd + K_C I_FD (the lead-lags' gain is 1)
        if not v["VRMIN"] <= v_r0 <= v["VRMAX"]:
            raise LimitsError(
                f"V_R at rest {v_r0:.3f} (E_fd {levels.output0:.3f} + K_C {v['KC']:g} x I_FD {levels.i_fd0:.3f}) lies "
                f"outside VRMIN..VRMAX {v['VRMIN']:g}..{v['VRMAX']:g}: the record's limits do not hold the recorded "
                "operating point"
            )
        e = regulator_error(x, reference, lag(x.v_t, v["TR"], x.dt))
        # K_R, the second lead-lag, then the first with its non-windup limit, and the limiter
        w = v_r0 + v["KR"] * lead_lag(e, v["TC2"], v["TB2"], x.dt)
        v_r = nonwindup_lead_lag(w, v["TC1"], v["TB1"], x.dt, v["VRMIN"], v["VRMAX"], v_r0)
        u = np.clip(v_r, v["VRMIN"], v["VRMAX"]) - loading
        lo, hi = v["VRMIN"] * levels.v_t, v["VRMAX"] * levels.v_t - loading
        return nonwindup_lag(u, v["T1"], x.dt, lo, hi, levels.output0) - levels.output0
