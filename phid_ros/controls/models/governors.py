"""Turbine-governors as PSS/E defines them (output P_m): TGOV1, IEEEG1, HYGOV."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from phid_ros.controls.models.base import (
    ControlModel,
    ControlParameter,
    register,
)
from phid_ros.controls.models.blocks import (
    Array,
    ControlInputs,
    first_order,
    lag,
    lead_lag,
    transfer,
)


@register
class TGOV1(ControlModel):
    """Steam turbine-governor: (P_ref - dw/R) through 1/(1 + sT_1), (1 + sT_2)/(1 + sT_3), less D_t dw."""

    name = "TGOV1"
    kind = "governor"
    description = "steam turbine-governor (PSS/E TGOV1)"
    in_andes = True
    pslf_trailing_zeros = 0
    parameters = (
        ControlParameter("R", "pu", 0.05, 0.01, 0.5, "permanent droop"),
        ControlParameter("T1", "s", 0.5, 0.02, 5.0, "governor (valve) time constant"),
        ControlParameter("VMAX", "pu", 1.0, 0.5, 1.5, "maximum valve position", limit=True),
        ControlParameter("VMIN", "pu", 0.0, -0.5, 0.5, "minimum valve position", limit=True),
        ControlParameter("T2", "s", 1.0, 0.0, 20.0, "turbine lead time constant"),
        ControlParameter("T3", "s", 3.0, 0.05, 30.0, "turbine lag (reheat) time constant"),
        ControlParameter("Dt", "pu", 0.0, 0.0, 5.0, "turbine damping", absent=0.0),
    )

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        valve = lag(reference * x.reference_step - x.speed / values["R"], values["T1"], x.dt)
        return lead_lag(valve, values["T2"], values["T3"], x.dt) - values["Dt"] * x.speed


@register
class IEEEG1(ControlModel):
    """IEEE type 1 steam turbine-governor (PSS/E IEEEG1): the speed deviation through
    K (1 + sT_2)/(1 + sT_1), the servo 1/(1 + sT_3) to the valve, then the steam chest 1/(1 + sT_4),
    the reheater 1/(1 + sT_5), the crossover 1/(1 + sT_6) and 1/(1 + sT_7) in series, each stage's
    share K_1, K_3, K_5, K_7 of this shaft's power. A fit has one reheat stage (K_1 + K_3 = 1, the
    stages marked "held out" at 0: short tests do not separate them); a record's are all simulated,
    and the second shaft's shares (K_2, K_4, K_6, K_8), which drive another machine, are refused."""

    name = "IEEEG1"
    kind = "governor"
    icons = (("JBUS", 0), ("M", 0))  # the low-pressure shaft's machine: none (a tandem compound)
    icons_simulated = ("JBUS", "M")
    description = "IEEE type 1 steam turbine-governor, one reheat stage (PSS/E IEEEG1)"
    in_andes = True
    pslf_trailing_zeros = 15  # its deadbands and valve table, unused
    parameters = (
        ControlParameter("K", "pu", 20.0, 2.0, 100.0, "governor gain (1/droop)"),
        ControlParameter("T1", "s", 0.0, 0.0, 0.0, "governor lag (held out of a fit)", held=True),
        ControlParameter("T2", "s", 0.0, 0.0, 0.0, "governor lead (held out of a fit)", held=True),
        ControlParameter("T3", "s", 0.1, 0.02, 2.0, "servo time constant"),
        ControlParameter("UO", "pu/s", 1.0, 0.01, 5.0, "maximum valve opening rate", limit=True),
        ControlParameter("UC", "pu/s", -1.0, -5.0, -0.01, "maximum valve closing rate", limit=True),
        ControlParameter("PMAX", "pu", 1.0, 0.5, 1.5, "maximum valve position", limit=True),
        ControlParameter("PMIN", "pu", 0.0, -0.5, 0.5, "minimum valve position", limit=True),
        ControlParameter("T4", "s", 0.3, 0.02, 2.0, "steam chest time constant"),
        ControlParameter("K1", "", 0.3, 0.02, 0.98, "high-pressure share"),
        ControlParameter("K2", "", 0.0, 0.0, 0.0, "high-pressure share on a second shaft (held out)", held=True),
        ControlParameter("T5", "s", 7.0, 0.5, 30.0, "reheater time constant"),
        ControlParameter("K3", "", 0.7, 0.02, 0.98, "low-pressure share (1 - K1)", held=True),
        ControlParameter("K4", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("T6", "s", 0.0, 0.0, 0.0, "crossover time constant (held out of a fit)", held=True),
        ControlParameter("K5", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("K6", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("T7", "s", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("K7", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("K8", "", 0.0, 0.0, 0.0, "(held out)", held=True),
    )

    def start(self, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        # TGOV1 is IEEEG1 with a steam chest of no delay: valve lag T1, reheat lead-lag T2/T3
        return self.started_from(
            earlier,
            "TGOV1",
            lambda t: {
                "K": 1.0 / t["R"],
                "T3": 0.05,
                "T4": t["T1"],
                "K1": min(max(t["T2"] / t["T3"], 0.05), 0.95),
                "T5": t["T3"],
            },
        )

    def completed(self, values: Mapping[str, float]) -> dict[str, float]:
        # the servo's and the steam chest's lags are in series on one signal: in small signal
        # they commute, so the data give the pair, not which is which; the servo is given the
        # shorter (IEEE's typical data: servo 0.1-0.2 s, steam chest 0.2-0.4 s)
        servo, chest = sorted((values["T3"], values["T4"]))
        return {**values, "T3": servo, "T4": chest, "K3": 1.0 - values["K1"]}

    def recorded(self, values: Mapping[str, float]) -> dict[str, float]:
        # every stage a record gives is simulated; the shares of a second (low-pressure) shaft
        # drive another machine, which a single unit's validation does not have
        second = {k: values[k] for k in ("K2", "K4", "K6", "K8") if values[k] != 0.0}
        if second:
            named = ", ".join(f"{k} = {v:g}" for k, v in second.items())
            raise ValueError(
                f"a second shaft's shares ({named}) drive another machine, which phid does not simulate: "
                "a cross-compound unit is not validated here"
            )
        negative = [k for k in ("T1", "T2", "T6", "T7") if values[k] < 0.0]
        if negative:
            raise ValueError(f"{', '.join(negative)} negative: a time constant is 0 (no lag) or positive")
        if values["T2"] > 0.0 and values["T1"] <= 0.0:
            raise ValueError(f"T2 = {values['T2']:g} s with T1 = 0: the governor's lead needs a lag")
        return dict(values)

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        # the load reference in pu power: the valve moves by it in steady state; the speed through
        # the governor's K (1 + sT_2)/(1 + sT_1), the servo, then the steam chest, the reheater, the
        # crossover and the last stage in series, each stage's share of the shaft's power
        speed = lead_lag(v["K"] * x.speed, v["T2"], v["T1"], x.dt)
        valve = lag(reference * x.reference_step - speed, v["T3"], x.dt)
        out = np.zeros_like(valve)
        stage = valve
        for t_stage, share in (("T4", "K1"), ("T5", "K3"), ("T6", "K5"), ("T7", "K7")):
            stage = lag(stage, v[t_stage], x.dt)
            out += v[share] * stage
        return out


@register
class HYGOV(ControlModel):
    """Hydro turbine-governor (PSS/E HYGOV), linearised about the scenario's operating point: the
    speed error less R times the gate command, through 1/(1 + sT_f) and the PI (1 + sT_r)/(r T_r s),
    the gate servo 1/(1 + sT_g); the water column (q = g sqrt(h), dq/dt = (1 - h)/T_w) and
    P_m = A_t h (q - q_NL) - D_turb g dw. At rated head the gate g0 = P_m0/A_t + q_NL, so a gate
    step moves P_m by A_t (1 - (q0 - q_NL) s T_w)/(1 + s g0 T_w/2): the water hammer's
    non-minimum phase."""

    name = "HYGOV"
    kind = "governor"
    description = "hydro turbine-governor (PSS/E HYGOV), linearised at the operating point"
    in_andes = True
    andes_names = {"TW": "Tw", "Dturb": "Dt"}
    parameters = (
        ControlParameter("R", "pu", 0.05, 0.01, 0.2, "permanent droop"),
        ControlParameter("r", "pu", 0.5, 0.05, 2.0, "temporary droop"),
        ControlParameter("Tr", "s", 5.0, 0.5, 30.0, "governor time constant (reset)"),
        ControlParameter("Tf", "s", 0.05, 0.005, 0.5, "filter time constant"),
        ControlParameter("Tg", "s", 0.5, 0.05, 2.0, "gate servo time constant"),
        ControlParameter("VELM", "pu/s", 0.2, 0.01, 1.0, "gate velocity limit", limit=True),
        ControlParameter("GMAX", "pu", 1.0, 0.5, 1.5, "maximum gate opening", limit=True),
        ControlParameter("GMIN", "pu", 0.0, 0.0, 0.5, "minimum gate opening", limit=True),
        ControlParameter("TW", "s", 1.0, 0.2, 5.0, "water inertia time constant"),
        # the small-signal response is unchanged when A_t, R, r and T_W scale together and q_NL
        # inversely (g0 = P_m0/A_t + q_NL): A_t is held at its typical value, 1/(g_FL - g_NL)
        ControlParameter("At", "pu", 1.2, 1.2, 1.2, "turbine gain (held: see the class)", held=True),
        ControlParameter("Dturb", "pu", 0.0, 0.0, 2.0, "turbine damping", absent=0.0),
        ControlParameter("qNL", "pu", 0.08, 0.0, 0.3, "no-load flow"),
    )

    def response(self, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        if not np.isfinite(x.p_m0):
            return np.full(len(x.speed), np.nan)  # no operating point: the model does not apply
        g0 = x.p_m0 / v["At"] + v["qNL"]
        q0 = g0  # at rated head
        # the reference in pu power: the gate command moves by R/A_t of it per pu
        u = reference * v["R"] / v["At"] * x.reference_step - x.speed
        gate_num = first_order(v["Tr"])
        gate_den = np.polyadd(np.polymul([v["r"] * v["Tr"], 0.0], first_order(v["Tf"])), v["R"] * first_order(v["Tr"]))
        num = v["At"] * np.polymul(gate_num, [-(q0 - v["qNL"]) * v["TW"], 1.0])
        den = np.polymul(np.polymul(gate_den, first_order(v["Tg"])), first_order(g0 * v["TW"] / 2))
        return transfer(u, num, den, x.dt) - v["Dturb"] * g0 * x.speed
