"""An independent salient-pole plant: STEPS's GENSAL (PSS/E's model) on a single-machine infinite bus.

None of phid's equations produce these recordings. STEPS (Simulation Toolkit for Electrical
Power Systems, Changgang Li, Shandong University, https://github.com/changgang/steps, MIT) is
built from its source: ``benchmarks/steps_build.sh`` (the ``stepspy`` wheel's library needs a
newer glibc than these machines have). The case is phid's simulator's own network (0.12 + 0.08
pu on the 1000 MVA machine base to the infinite bus, here on STEPS's 100 MVA system base, so
every conversion between the two bases is exercised), P = 0.8 at V_t = 1.0. ``run`` returns the
channels of phid's CSV contract on the machine base; ``write_set`` adds sensor noise and writes
a CSV scenario set (``benchmarks/steps_sets.py`` makes the sets from the command line).

STEPS's habits, found by checking its data as the ANDES sets were checked:

* a disturbance takes effect in the step after it is applied, through the run-to-time call: each
  is applied at the end of the step before the event's time;
* a bus meter's ANGLE IN RAD reads 0: the angle in degrees is used;
* its meters have no rotor speed in pu, only the speed deviation;
* the infinite bus is a GENCLS with H = 0 behind a tiny source reactance, its voltage stepped
  through the GENCLS's internal voltage (STEPS has no slack-voltage event);
* the fault is a shunt admittance in pu on the system base;
* a governor's "mechanical power reference" is what its summing point takes: TGOV1's is R P_m
  (0.04 at P_m = 0.8, R = 0.05), IEEEG1's the valve position P_m/(K_1 + K_3 + K_5 + K_7), so a
  load-reference step scales it;
* its GENSAL saturates on |psi''| in both axes, GENROU's form (``gensal.cpp``: the d-axis input
  less S psi''_d, the q axis's plus S psi''_q (X_q - X_l)/(X_d - X_l)), not PSS/E's GENSAL form (on
  E'_q, d axis only): on ``gensal-sat`` the diagnosis rightly names the GENROU form;
* its swing equation is PSS/E's, (P_m - D dw)/(1 + dw) - T_e: phid's D (the paper's (5)) is
  D + P_m0, 1.2 here, and ``TRUTH`` says so (``phid export`` writes D - P_m0 to a .dyr).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from phid_ros.model.conventions import network_to_dq
from phid_ros.sim.runner import SimulationConfig
from phid_ros.sim.scenarios import Scenario
from test.plants import noisy_set

SYSTEM_MVA = 100.0
MACHINE_MVA = 1000.0
KV = 20.0
TO_SYSTEM = SYSTEM_MVA / MACHINE_MVA


@dataclass(frozen=True)
class Machine:
    """A GENSAL record (PSS/E's order of fields, machine base) and the controls beside it."""

    gensal: Mapping[str, float]
    exciter: str = ""  # a PSS/E .dyr record's model and fields after the id, e.g. "'SEXS' 1 0.25 4.0 200 0.02 -4 6"
    governor: str = ""

    def dyr(self) -> str:
        g = self.gensal
        fields = ("Td0p", "Td0pp", "Tq0pp", "H", "D", "Xd", "Xq", "Xdp", "Xpp", "Xl", "S1", "S12")
        lines = ["1 'GENSAL' 1 " + " ".join(f"{g[k]:.6g}" for k in fields) + " /"]
        lines += [f"1 {rec} /" for rec in (self.exciter, self.governor) if rec]
        lines.append("2 'GENCLS' 1 0.0 0.0 /")
        return "\n".join(lines) + "\n"


# a hydro unit's salient-pole data (the typical ranges of IEEE Std 1110 for salient-pole machines),
# on its own base; X'_q is X_q (no q-axis field winding), so the fourth-order model's T'_q0 is not
# a parameter of this machine
GENSAL_BASE = {"Td0p": 5.0, "Td0pp": 0.05, "Tq0pp": 0.08, "H": 3.48, "D": 0.4, "Xd": 1.10, "Xq": 0.70}
GENSAL_BASE.update({"Xdp": 0.32, "Xpp": 0.22, "Xl": 0.15, "S1": 0.0, "S12": 0.0})
SEXS = "'SEXS' 1 0.2 5.0 100.0 0.05 -5.0 5.0"
TGOV1 = "'TGOV1' 1 0.05 0.5 1.05 0.0 2.0 6.0 0.0"
# a DC exciter and a reheat steam governor, the two of phid's other control models STEPS has (its
# governors are TGOV1, IEEEG1-3, IEESGO, GAST2A, URCSCT: no HYGOV). IEEET1: TR, KA, TA, VRMAX,
# VRMIN, KE, TE, KF, TF, switch, E1, SE(E1), E2, SE(E2) (zero saturation: STEPS then leaves it
# out). IEEEG1: JBUS, M, K, T1, T2, T3, UO, UC, PMAX, PMIN, T4, K1, K2, T5, K3, ... K8, the rate
# limits wide (phid's paths are small-signal; the limits are not what this set checks)
IEEET1 = "'IEEET1' 1 0.0 50.0 0.05 5.0 -5.0 1.0 0.5 0.05 1.0 0 0.0 0.0 0.0 0.0"
IEEEG1 = "'IEEEG1' 1 0 0 20.0 0.0 0.0 0.1 5.0 -5.0 1.1 0.0 0.3 0.3 0.0 7.0 0.7 0.0 0.0 0.0 0.0 0.0 0.0 0.0"
MACHINES: dict[str, Machine] = {
    "gensal": Machine(GENSAL_BASE),
    "gensal-sat": Machine({**GENSAL_BASE, "S1": 0.1, "S12": 0.4}),
    "gensal-controls": Machine(GENSAL_BASE, SEXS, TGOV1),
    "gensal-sat-controls": Machine({**GENSAL_BASE, "S1": 0.1, "S12": 0.4}, SEXS, TGOV1),
    "gensal-ieeet1-ieeeg1": Machine(GENSAL_BASE, IEEET1, IEEEG1),
}
P_M0 = 0.8  # the case's P_m (SimulationConfig's operating point)
TRUTH = {
    name: {
        "H": m.gensal["H"],
        "D": m.gensal["D"] + P_M0,  # phid's power-form D: PSS/E's torque form adds P_m0 (see above)
        "X_d": m.gensal["Xd"],
        "X_q": m.gensal["Xq"],
        "X_d_prime": m.gensal["Xdp"],
        # no q-axis field winding: the fourth-order model's q circuit is the damper (identification
        # finds X'_q = X'', T'_q0 = T''_q0); with the damper named, the diagnosis moves X'_q to X_q
        "X_q_prime": m.gensal["Xpp"],
        "T_d0_prime": m.gensal["Td0p"],
        "T_q0_prime": m.gensal["Tq0pp"],
    }  # fmt: skip
    for name, m in MACHINES.items()
}

RAW = """0, {sbase:.2f}, 33, 0, 0, {f:.6f}
PHID SINGLE MACHINE, INFINITE BUS
GENERATOR {mbase:.0f} MVA {kv:.0f} KV
1, "GEN", {kv:.2f}, 2, 1, 1, 1, {v:.6f}, 0.0, 1.1, 0.9, 1.1, 0.9, {f:.1f}
2, "INF", {kv:.2f}, 3, 1, 1, 1, {v_inf:.6f}, 0.0, 1.1, 0.9, 1.1, 0.9, {f:.1f}
0 / END OF BUS DATA, BEGIN LOAD DATA
0 / END OF LOAD DATA, BEGIN FIXED SHUNT DATA
0 / END OF FIXED SHUNT DATA, BEGIN GENERATOR DATA
{generators}0 / END OF GENERATOR DATA, BEGIN TRANSMISSION LINE DATA
1, 2, "1", 0.0, {x_e:.6f}, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1, 1, 0.0, 1, 1.0, 0, 0.0, 0, 0.0, 0, 0.0
0 / END OF TRANSMISSION LINE DATA, BEGIN TRANSFORMER DATA
0 / END OF TRANSFORMER DATA, BEGIN AREA DATA
0 / END OF AREA DATA, BEGIN TWO-TERMINAL HVDC DATA
'0' / END OF TWO-TERMINAL HVDC DATA, BEGIN VSC HVDC LINE DATA
'0' / END OF VSC HVDC LINE DATA, BEGIN IMPEDANCE CORRECTION DATA
0 / END OF IMPEDANCE CORRECTION DATA, BEGIN MULTI-TERMINAL HVDC DATA
0 / END OF MULTI-TERMINAL HVDC DATA, BEGIN MULTI-SECTION LINE DATA
0 / END OF MULTI-SECTION LINE DATA, BEGIN ZONE DATA
0 / END OF ZONE DATA, BEGIN INTER-AREA TRANSFER DATA
0 / END OF INTER-AREA TRANSFER DATA, BEGIN OWNER DATA
0 / END OF OWNER DATA, BEGIN FACTS DEVICE DATA
0 / END OF FACTS DEVICE DATA, BEGIN SWITCHED SHUNT DATA
0 / END OF SWITCHED SHUNT DATA, BEGIN GNE DATA
0 / END OF GNE DATA, BEGIN INDUCTION MACHINE DATA
0 / END OF INDUCTION MACHINE DATA
Q
"""
# the machine (P scheduled, V held) and the infinite bus: a 10^6 MVA source behind 10^-4 pu
OWNERSHIP = "1, 1.0, 0, 0.0, 0, 0.0, 0, 0.0, 0, 0.0, 0"
GENERATORS = (
    '1, "1", {p_mw:.6f}, 0.0, 9999.0, -9999.0, {v:.6f}, 0, {mbase:.1f}, 0.0, 0.25, 0.0, 0.0, 1.0, 1, 100.0, '
    "9999.0, -9999.0, " + OWNERSHIP + "\n"
    '2, "1", 0.0, 0.0, 99999.0, -99999.0, {v_inf:.6f}, 0, 1e6, 0.0, 1e-4, 0.0, 0.0, 1.0, 1, 100.0, '
    "99999.0, -99999.0, " + OWNERSHIP + "\n"
)
GEN, INF = (1, "1"), (2, "1")
METERS = (
    ("rotor angle in deg", "delta"),
    ("rotor speed deviation in pu", "omega"),
    ("terminal voltage in pu", "v_t"),
    ("terminal active power in pu on mbase", "p_e"),
    ("terminal reactive power in pu on mbase", "q_e"),
    ("excitation voltage in pu", "v_f"),
    ("mechanical power in pu on mbase", "p_m"),
)


@dataclass
class Case:
    """One scenario's STEPS simulator, set up and at its steady state."""

    machine: Machine
    cfg: SimulationConfig = field(default_factory=SimulationConfig)
    workdir: Path = field(default_factory=lambda: Path(tempfile.mkdtemp(prefix="phid-steps-")))

    def __post_init__(self) -> None:
        from stepspy import STEPS

        cfg = self.cfg
        v_inf = cfg.plant().steady_state(cfg.operating_point).v_inf  # Q = 0.4 at V_t = 1.0, as phid's case
        x_e = (cfg.network.x_transformer + cfg.network.x_line) * TO_SYSTEM
        raw = self.workdir / "smib.raw"
        raw.write_text(
            RAW.format(
                sbase=SYSTEM_MVA,
                f=cfg.f_nominal_hz,
                mbase=MACHINE_MVA,
                kv=KV,
                v=cfg.operating_point.v_t,
                v_inf=v_inf,
                generators=GENERATORS.format(
                    p_mw=cfg.operating_point.p_e * MACHINE_MVA,
                    v=cfg.operating_point.v_t,
                    mbase=MACHINE_MVA,
                    v_inf=v_inf,  # noqa: E501
                ),
                x_e=x_e,
            )
        )
        (self.workdir / "smib.dyr").write_text(self.machine.dyr())
        self.s = STEPS(is_default=False, log_file=os.devnull)
        self.s.set_allowed_maximum_bus_number(100)
        self.s.load_powerflow_data(str(raw), "PSS/E")
        self.s.solve_powerflow("NR")
        self.s.load_dynamic_data(str(self.workdir / "smib.dyr"), "psse")
        for meter, _ in METERS:
            self.s.prepare_generator_meter(GEN, meter)
        self.s.prepare_bus_meter(1, "angle in deg")  # ANGLE IN RAD reads 0

    def run(self, scenario: Scenario, dt: float = 0.001) -> dict[str, np.ndarray]:
        """Simulate through ``scenario``: the CSV contract's channels on a ``dt`` grid, machine base."""
        s = self.s
        if not scenario.generator_damping:
            s.set_generator_related_model_data(GEN, "gen", "D", 0.0)
        s.set_dynamic_simulation_time_step(dt)
        s.set_dynamic_simulator_output_file(str(self.workdir / "out"))
        s.start_dynamic_simulation()
        n = int(round(scenario.duration / dt))
        k_event = int(round(scenario.t_event / dt))
        k_clear = int(round(scenario.t_clear / dt)) if scenario.t_clear is not None else None
        values = np.empty((n, len(METERS) + 1))
        for k in range(n):
            # applied at the end of the step before: it takes effect in the next run-to-time
            if k == k_event:
                self._disturb(scenario)
            if k == k_clear:
                s.clear_bus_fault(1, "three phase fault")
            if k:
                s.run_dynamic_simulation_to_time(k * dt)
            values[k] = [s.get_user_meter_value(i) for i in range(1, len(METERS) + 2)]
        s.stop_dynamic_simulation()
        out = {name: values[:, i] for i, (_, name) in enumerate(METERS)}
        out["delta"] = np.radians(out["delta"])
        out["omega"] = 1.0 + out["omega"]
        out["theta_t"] = np.radians(values[:, -1])
        v = out["v_t"] * np.exp(1j * out["theta_t"])
        i_dq = network_to_dq(np.conj((out["p_e"] + 1j * out["q_e"]) / v), out["delta"])
        out["i_d"], out["i_q"] = i_dq.real, i_dq.imag
        return {"t": np.arange(n) * dt, **out}

    def _disturb(self, scenario: Scenario) -> None:
        s = self.s
        if scenario.kind == "torque_step":
            if self.machine.governor:  # the reference is in proportion to P_m (see above): scaled, not added to
                p_ref, p_m = (
                    s.get_generator_mechanical_power_reference_in_pu(GEN),
                    s.get_generator_mechanical_power_in_pu(GEN),
                )
                s.set_generator_mechanical_power_reference_in_pu(GEN, p_ref * (p_m + scenario.magnitude) / p_m)
            else:
                p_m = s.get_generator_mechanical_power_in_pu(GEN)
                s.set_generator_mechanical_power_in_pu(GEN, p_m + scenario.magnitude)
        elif scenario.kind == "field_step":
            if self.machine.exciter:
                v_ref = s.get_generator_voltage_reference_in_pu(GEN)
                s.set_generator_voltage_reference_in_pu(GEN, v_ref * scenario.magnitude)
            else:
                e_fd = s.get_generator_excitation_voltage_in_pu(GEN)
                s.set_generator_excitation_voltage_in_pu(GEN, e_fd * scenario.magnitude)
        elif scenario.kind == "voltage_step":
            e = s.get_generator_excitation_voltage_in_pu(INF)
            s.set_generator_excitation_voltage_in_pu(INF, e * scenario.magnitude)
        else:
            b = -1.0 / (scenario.fault_reactance * TO_SYSTEM)  # a reactance on the machine base
            s.set_bus_fault(1, "three phase fault", (0.0, b))


def write_set(
    folder: Path, machine: Machine, scenarios: Sequence[Scenario], *, seed: int = 0, noise: float = 1.0
) -> Path:
    """Each scenario simulated by STEPS, sensor noise added (``noise`` x the simulator's), as a CSV set."""
    return noisy_set(
        folder,
        scenarios,
        lambda sc: Case(machine).run(sc),
        mva=MACHINE_MVA,
        source="steps",
        description="STEPS GENSAL single machine, infinite bus",
        seed=seed,
        noise=noise,
    )
