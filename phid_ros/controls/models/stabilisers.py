"""Power system stabilisers as PSS/E defines them (output V_S): IEEEST, PSS2A, PSS2B."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from phid_ros.controls.models.base import (
    ControlModel,
    ControlParameter,
    OperatingLevels,
    register,
)
from phid_ros.controls.models.blocks import (
    Array,
    ControlInputs,
    lag,
    lead_lag,
    lead_lags_in_order,
    transfer,
    washout,
)


class Stabiliser(ControlModel):
    """A stabiliser's limits as PSS/E simulates them: V_S, its small-signal path's output, held
    within the output limits (no state limit inside the path)."""

    kind = "stabiliser"

    def limited(
        self, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return self.output_clipped(values, x, reference, levels)


@register
class IEEEST(Stabiliser):
    """IEEE stabiliser (PSS/E IEEEST) on the electrical power (input code 3): P_e through the
    filter (1 + sA_5 + s^2 A_6)/((1 + sA_1 + s^2 A_2)(1 + sA_3 + s^2 A_4)), two lead-lags
    (1 + sT_1)/(1 + sT_2), (1 + sT_3)/(1 + sT_4), K_S and the washout sT_5/(1 + sT_6), its output
    V_S within LSMIN..LSMAX, added at the voltage regulator's summing point.

    Fitted from a recorded stabiliser output against the recorded P_e, or, where the output is not
    recorded, from its effect on E_fd through the exciter (:mod:`phid_ros.controls.stabiliser_effect`).
    The torsional filter
    (A_1..A_6, for a steam unit's shaft modes) is held out at 0, a wire; the washout's gain is
    T_5/T_6, which K_S carries, so T_5 = T_6; the output's enabling band VCU/VCL at 0 (not used)."""

    name = "IEEEST"
    icons = (("MODE", 3), ("BUSR", 0))  # the input: the machine's electrical power; its own bus
    icons_simulated = ("MODE",)
    description = "IEEE stabiliser on the electrical power (PSS/E IEEEST, input code 3)"
    outside_path = ("VCU", "VCL")
    in_andes = True
    parameters = (
        *(
            ControlParameter(
                n, "s" if n in ("A1", "A3", "A5") else "s2", 0.0, 0.0, 0.0, "torsional filter (held out)", held=True
            )
            for n in ("A1", "A2", "A3", "A4", "A5", "A6")
        ),
        ControlParameter("T1", "s", 0.2, 0.0, 5.0, "first lead time constant", absent=0.0),
        ControlParameter("T2", "s", 0.05, 0.002, 5.0, "first lag time constant"),
        ControlParameter("T3", "s", 0.2, 0.0, 5.0, "second lead time constant", absent=0.0),
        ControlParameter("T4", "s", 0.05, 0.002, 5.0, "second lag time constant"),
        ControlParameter("T5", "s", 3.0, 3.0, 3.0, "washout numerator (T_6: K_S carries the gain)", held=True),
        ControlParameter("T6", "s", 3.0, 0.3, 30.0, "washout time constant"),
        ControlParameter("KS", "pu", -1.0, -100.0, 100.0, "stabiliser gain (pu of V_S per pu of P_e)"),
        ControlParameter("LSMAX", "pu", 0.1, 0.005, 0.5, "maximum stabiliser output", limit=True),
        ControlParameter("LSMIN", "pu", -0.1, -0.5, -0.005, "minimum stabiliser output", limit=True),
        ControlParameter("VCU", "pu", 0.0, 0.0, 0.0, "output enabled below this V_T (0: not used)", held=True),
        ControlParameter("VCL", "pu", 0.0, 0.0, 0.0, "output enabled above this V_T (0: not used)", held=True),
    )
    simulated_limits = ("LSMAX", "LSMIN")
    output_limits = ("LSMIN", "LSMAX")
    simulated_limits_how = "V_S within LSMIN..LSMAX (PSS/E IEEEST)"

    def completed(self, values: Mapping[str, float]) -> dict[str, float]:
        return {**values, **lead_lags_in_order(values), "T5": values["T6"]}

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values  # a record's as written (a fit's values come completed: T_5 = T_6)
        if x.p_e is None:
            return np.full(len(x.v_t), np.nan)  # no electrical power: the model does not apply
        led = lead_lag(lead_lag(x.p_e, v["T1"], v["T2"], x.dt), v["T3"], v["T4"], x.dt)
        if any(v[a] for a in ("A1", "A2", "A3", "A4", "A5", "A6")):
            num = np.array([v["A6"], v["A5"], 1.0])
            den = np.polymul([v["A2"], v["A1"], 1.0], [v["A4"], v["A3"], 1.0])
            led = transfer(led, np.trim_zeros(num, "f"), np.trim_zeros(den, "f"), x.dt)
        # K_S sT_5/(1 + sT_6) = K_S (T_5/T_6) (1 - 1/(1 + sT_6))
        return v["KS"] * v["T5"] / v["T6"] * (led - lag(led, v["T6"], x.dt))


@register
class PSS2A(Stabiliser):
    """IEEE dual-input stabiliser (PSS/E PSS2A, IEEE 421.5 PSS2A) on the rotor speed (input code 1)
    and the electrical power (code 3): each input through two washouts, the speed then 1/(1 + sT_6),
    the power K_S2/(1 + sT_7) (the integral of accelerating power: K_S2 = T_7/(2H)); their sum, the
    power's share K_S3, through the ramp-tracking filter [(1 + sT_8)/(1 + sT_9)^M]^N, less the power's
    path; then K_S1 and two lead-lags, V_S within VSTMIN..VSTMAX.

    Fitted from a recorded stabiliser output against the recorded speed and P_e (a recorder
    without the speed cannot fit it). As IEEE 421.5's sample data set it, the washouts and T_7 are
    one time constant (T_W1 = T_W2 = T_W3 = T_7, T_W4 = 0: a wire), T_6 = 0, K_S3 = 1, M = 5, N = 1
    and T_8 = M T_9 (the filter tracks a ramp of mechanical power with no error): the fit frees
    T_W1, K_S2, T_9, K_S1 and the lead-lags. A record's constants are all simulated as written."""

    name = "PSS2A"
    # PSS/E's ICONs: input 1 the rotor speed, input 2 the electrical power (both the machine's own
    # bus), then the ramp-tracking filter's orders
    icons = (("ICS1", 1), ("IB1", 0), ("ICS2", 3), ("IB2", 0), ("M", 5), ("N", 1))
    icons_simulated = ("ICS1", "ICS2", "M", "N")
    needs = ("omega",)
    description = "IEEE dual-input stabiliser on the speed and the electrical power (PSS/E PSS2A)"
    parameters: tuple[ControlParameter, ...] = (
        ControlParameter("TW1", "s", 2.0, 0.5, 30.0, "washout time constant (the speed's first)"),
        ControlParameter("TW2", "s", 2.0, 2.0, 2.0, "the speed's second washout (T_W1 in a fit)", held=True),
        ControlParameter("T6", "s", 0.0, 0.0, 0.0, "the speed's lag (0 in a fit: a wire)", held=True),
        ControlParameter("TW3", "s", 2.0, 2.0, 2.0, "the power's first washout (T_W1 in a fit)", held=True),
        ControlParameter("TW4", "s", 0.0, 0.0, 0.0, "the power's second washout (0 in a fit: a wire)", held=True),
        ControlParameter("T7", "s", 2.0, 2.0, 2.0, "the power's integrating lag (T_W1 in a fit)", held=True),
        ControlParameter("KS2", "pu", 0.3, 0.01, 10.0, "the power's gain (T_7 / 2H)"),
        ControlParameter("KS3", "", 1.0, 1.0, 1.0, "the power's share before the filter (1 in a fit)", held=True),
        ControlParameter("T8", "s", 0.5, 0.5, 0.5, "ramp-tracking lead (M T_9 in a fit)", held=True),
        ControlParameter("T9", "s", 0.1, 0.01, 1.0, "ramp-tracking lag"),
        ControlParameter("KS1", "pu", 10.0, -200.0, 200.0, "stabiliser gain"),
        ControlParameter("T1", "s", 0.15, 0.0, 5.0, "first lead time constant", absent=0.0),
        ControlParameter("T2", "s", 0.03, 0.002, 5.0, "first lag time constant"),
        ControlParameter("T3", "s", 0.15, 0.0, 5.0, "second lead time constant", absent=0.0),
        ControlParameter("T4", "s", 0.03, 0.002, 5.0, "second lag time constant"),
        ControlParameter("VSTMAX", "pu", 0.1, 0.005, 0.5, "maximum stabiliser output", limit=True),
        ControlParameter("VSTMIN", "pu", -0.1, -0.5, -0.005, "minimum stabiliser output", limit=True),
    )
    simulated_limits = ("VSTMAX", "VSTMIN")
    output_limits = ("VSTMIN", "VSTMAX")
    simulated_limits_how = "V_S within VSTMIN..VSTMAX (PSS/E PSS2A)"
    M, N = 5, 1  # the ramp-tracking filter's orders phid simulates (icons_simulated holds a record to them)

    def completed(self, values: Mapping[str, float]) -> dict[str, float]:
        # a fit's structure (see the class); the lead-lags in one order
        tw = values["TW1"]
        return {
            **values,
            **lead_lags_in_order(values),
            "TW2": tw,
            "TW3": tw,
            "T7": tw,
            "T8": self.M * values["T9"],
        }

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        if x.p_e is None:
            return np.full(len(x.v_t), np.nan)  # no electrical power: the model does not apply
        speed = lag(washout(washout(x.speed, v["TW1"], x.dt), v["TW2"], x.dt), v["T6"], x.dt)
        power = v["KS2"] * lag(washout(washout(x.p_e, v["TW3"], x.dt), v["TW4"], x.dt), v["T7"], x.dt)
        tracked = speed + v["KS3"] * power
        for _ in range(self.N):
            tracked = lead_lag(tracked, v["T8"], v["T9"], x.dt)
            for _ in range(self.M - 1):
                tracked = lag(tracked, v["T9"], x.dt)
        u = tracked - power
        return v["KS1"] * lead_lag(lead_lag(u, v["T1"], v["T2"], x.dt), v["T3"], v["T4"], x.dt)


@register
class PSS2B(PSS2A):
    """IEEE 421.5-2005's PSS2B (PSS/E PSS2B): PSS2A with a third lead-lag (1 + sT_10)/(1 + sT_11)
    after the other two and limits on its two inputs (VSI1MAX/VSI1MIN on the speed,
    VSI2MAX/VSI2MIN on the electrical power), which a stabiliser's small-signal play-in never
    reaches: written, said where a record's are played, not simulated.

    Fitted as PSS2A is (the same structure held), the third lead-lag free; started where PSS2A's
    fit ended, with the third a wire, so it fits at least as well and is named only where the third
    lead-lag earns it (the simplest within 5 % is named). The CONs' order is PSS2A's with T_10,
    T_11 after T_4 and the input limits before VSTMAX, VSTMIN (23 CONs, 6 ICONs): the order of
    PowerSystems.jl's PSS2B, and the one PSS/E itself was given in ALSETLab's OpenIPSL verification
    runs (NYPAModelTransformation, ``OpenIPSLVerification/VerificationRoutines/PSSE/Scripts/
    add_models_openipsl.py``: ``psspy.add_plant_model(..., "PSS2B", ..., 6, [1, 0, 3, 0, 0, 0], ...,
    23, [...])``), whose values read in this order are a coherent unit: the washouts and T_7 2 s,
    K_S2 0.1564, K_S3 1, K_S1 10, the lead-lags 0.25/0.03 and 0.15/0.015 s, T_10 = T_11 = 0, the
    input limits +-999 and V_S within +-0.1 (PSS/E's manual itself is not at hand here)."""

    name = "PSS2B"
    description = "IEEE dual-input stabiliser with a third lead-lag (PSS/E PSS2B, IEEE 421.5-2005)"
    parameters: tuple[ControlParameter, ...] = (
        *(p for p in PSS2A.parameters if not p.limit),
        ControlParameter("T10", "s", 0.1, 0.0, 5.0, "third lead time constant", absent=0.0),
        ControlParameter("T11", "s", 0.1, 0.002, 5.0, "third lag time constant"),
        ControlParameter("VSI1MAX", "pu", 2.0, 0.01, 10.0, "maximum of the speed input", limit=True),
        ControlParameter("VSI1MIN", "pu", -2.0, -10.0, -0.01, "minimum of the speed input", limit=True),
        ControlParameter("VSI2MAX", "pu", 2.0, 0.01, 10.0, "maximum of the electrical power input", limit=True),
        ControlParameter("VSI2MIN", "pu", -0.66, -10.0, -0.01, "minimum of the electrical power input", limit=True),
        *(p for p in PSS2A.parameters if p.limit),
    )
    simulated_limits_how = "V_S within VSTMIN..VSTMAX (PSS/E PSS2B)"
    LEAD_LAGS: ClassVar[tuple[tuple[str, str], ...]] = (("T1", "T2"), ("T3", "T4"), ("T10", "T11"))

    def start(self, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        # PSS2A is PSS2B with its third lead-lag a wire
        own = self.defaults()
        return self.started_from(
            earlier, "PSS2A", lambda a: {**{k: v for k, v in a.items() if k in own}, "T10": 0.1, "T11": 0.1}
        )

    def completed(self, values: Mapping[str, float]) -> dict[str, float]:
        return {**super().completed(values), **lead_lags_in_order(values, self.LEAD_LAGS)}

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        return lead_lag(super().response(values, x, reference), values["T10"], values["T11"], x.dt)
