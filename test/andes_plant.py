"""An independent plant: ANDES's GENROU/GENSAL on a single-machine infinite-bus case.

None of phid's equations produce these recordings (ANDES is a test extra). The case is phid's
simulator's own (phid_ros.sim: 0.12 + 0.08 pu to the infinite bus, P = 0.8, Q = 0.4 at
V_t = 1.0 on a 1000 MVA machine, here on ANDES's 100 MVA system base); V_f and P_m are held
(no exciter or governor) except where a scenario steps them. ``run`` returns the channels of
phid's CSV contract on the machine base; ``write_set`` adds sensor noise and writes a CSV
scenario set (``benchmarks/andes_sets.py`` makes the sets from the command line).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from phid_ros.sim.runner import SimulationConfig
from phid_ros.sim.scenarios import Scenario
from test.plants import noisy_set

SYSTEM_MVA = 100.0
MACHINE_MVA = 1000.0
KV = 20.0
TO_SYSTEM = SYSTEM_MVA / MACHINE_MVA


# machines for the independent sets (ANDES GENROU fields, machine base). ANDES 2.0 has no GENSAL
# (its .dyr reader maps GENSAL onto GENROU), so no set here is a salient-pole machine.
TABLE1_GENROU = {"fn": 50.0, "M": 6.96, "D": 0.4, "xd": 2.54, "xq": 2.41, "xd1": 0.5, "xq1": 0.814, "xl": 0.15}
TABLE1_GENROU.update({"Td10": 1.437, "Tq10": 0.1351, "S10": 0.0, "S12": 1.0})
MACHINES: dict[str, dict[str, float]] = {
    # X'_d = X'_q = X'': both dampers inert, GENROU is exactly the fourth-order model
    "genrou-4th": {**TABLE1_GENROU, "xq1": 0.5, "xd2": 0.5, "xq2": 0.5, "Td20": 0.03, "Tq20": 0.03},
    # the same with saturation (quadratic, on the air-gap flux, both axes): one effect missing
    "genrou-sat": {
        **TABLE1_GENROU,
        "xq1": 0.5,
        "xd2": 0.5,
        "xq2": 0.5,
        "Td20": 0.03,
        "Tq20": 0.03,
        "S10": 0.07,
        "S12": 0.45,
    },  # fmt: skip
    # strong dampers, no saturation: one effect missing. T''_q0 = 0.08 s is within a factor 1.7 of
    # T'_q0 = 0.135 s: the q axis's two circuits are hard to tell apart
    "genrou-sub": {**TABLE1_GENROU, "xd2": 0.25, "xq2": 0.25, "Td20": 0.04, "Tq20": 0.08},
    # the same with faster dampers (T''_q0 4.5 times below T'_q0)
    "genrou-sub-fast": {**TABLE1_GENROU, "xd2": 0.25, "xq2": 0.25, "Td20": 0.03, "Tq20": 0.03},
    # dampers on a machine whose q-axis transient is as typical round-rotor data have it (T'_q0 0.6 s,
    # T''_q0 0.05 s): the q axis's two circuits twelve-fold apart, unlike Table 1's 0.135 s
    "genrou-sub-typical": {**TABLE1_GENROU, "Tq10": 0.6, "xd2": 0.25, "xq2": 0.25, "Td20": 0.03, "Tq20": 0.05},
    # both
    "genrou-sat-sub": {**TABLE1_GENROU, "xd2": 0.3, "xq2": 0.3, "Td20": 0.03, "Tq20": 0.05, "S10": 0.07, "S12": 0.45},
}
# the eight fourth-order parameters each machine has (GENROU's H = M / 2; its X', T' are the base)
TRUTH = {
    name: {
        "H": m["M"] / 2,
        "D": m["D"],
        "X_d": m["xd"],
        "X_q": m["xq"],
        "X_d_prime": m["xd1"],
        "X_q_prime": m["xq1"],
        "T_d0_prime": m["Td10"],
        "T_q0_prime": m["Tq10"],
    }  # fmt: skip
    for name, m in MACHINES.items()
}


def system(record: Mapping[str, object] | None = None, dyr: Path | None = None, cfg: SimulationConfig | None = None):
    """The SMIB case with one machine, from an ANDES GENROU row or a PSS/E .dyr (not yet set up)."""
    import andes

    andes.config_logger(stream_level=40)
    cfg = cfg or SimulationConfig()
    ss = cfg.plant().steady_state(cfg.operating_point)
    s = andes.System(default_config=True)
    s.config.freq = cfg.f_nominal_hz
    s.add("Bus", {"idx": 1, "name": "G", "Vn": KV, "v0": 1.0})
    s.add("Bus", {"idx": 2, "name": "INF", "Vn": KV, "v0": ss.v_inf})
    x_e = (cfg.network.x_transformer + cfg.network.x_line) * TO_SYSTEM
    s.add("Line", {"idx": "L", "bus1": 1, "bus2": 2, "x": x_e, "r": 0.0, "b": 0.0, "Vn1": KV, "Vn2": KV})
    p_sys = cfg.operating_point.p_e / TO_SYSTEM
    s.add("PV", {"idx": "1_1", "bus": 1, "subidx": 1, "Sn": MACHINE_MVA, "Vn": KV, "p0": p_sys, "v0": 1.0})
    s.add("Slack", {"idx": "S", "bus": 2, "Sn": 1e5, "Vn": KV, "v0": ss.v_inf, "a0": 0.0})
    if dyr is not None:
        andes.io.psse.read_add(s, str(dyr))
        s.GENROU.fn.v[0] = cfg.f_nominal_hz  # the frequency is the case's; ANDES's reader defaults it to 60 Hz
    if record is not None:
        s.add("GENROU", {"idx": "G1", "bus": 1, "gen": "1_1", "Sn": MACHINE_MVA, "Vn": KV, **record})
    return s


EXCITERS = ("SEXS", "EXST1", "IEEET1")
GOVERNORS = ("TGOV1", "IEEEG1", "HYGOV")


def _control(s, names: Sequence[str]):
    return next((getattr(s, n) for n in names if getattr(s, n).n), None)


def disturb(s, scenario: Scenario) -> None:
    """The scenario's disturbance as ANDES events (the ramp back of phid's runner is left out).
    Where the unit has an exciter (governor), a field (torque) step is a step of its voltage
    (load) reference by ``magnitude`` pu, as a staged MOD-026 (MOD-027) test makes it."""
    dev = s.GENROU.idx.v[0]
    exciter, governor = _control(s, EXCITERS), _control(s, GOVERNORS)
    if scenario.kind == "field_step" and exciter is not None:
        s.add("Alter", {"t": scenario.t_event, "model": exciter.class_name, "dev": exciter.idx.v[0], "src": "vref0",
                        "attr": "v", "method": "+", "amount": scenario.magnitude})  # fmt: skip
    elif scenario.kind == "torque_step" and governor is not None:
        s.add("Alter", {"t": scenario.t_event, "model": governor.class_name, "dev": governor.idx.v[0], "src": "paux0",
                        "attr": "v", "method": "+", "amount": scenario.magnitude})  # fmt: skip
    elif scenario.kind == "torque_step":
        s.add("Alter", {"t": scenario.t_event, "model": "GENROU", "dev": dev, "src": "tm0", "attr": "v",
                        "method": "+", "amount": scenario.magnitude / TO_SYSTEM})  # fmt: skip
    elif scenario.kind == "field_step":
        s.add("Alter", {"t": scenario.t_event, "model": "GENROU", "dev": dev, "src": "vf0", "attr": "v",
                        "method": "*", "amount": scenario.magnitude})  # fmt: skip
    elif scenario.kind == "voltage_step":
        s.add("Alter", {"t": scenario.t_event, "model": "Slack", "dev": "S", "src": "v0", "attr": "v",
                        "method": "*", "amount": scenario.magnitude})  # fmt: skip
    else:
        s.add("Fault", {"bus": 1, "tf": scenario.t_event, "tc": scenario.t_clear,
                        "xf": scenario.fault_reactance * TO_SYSTEM, "rf": 0.0})  # fmt: skip


def run(s, scenario: Scenario, dt: float = 0.001) -> dict[str, np.ndarray]:
    """Simulate the set-up-to-be system through ``scenario``; the CSV contract's channels on a ``dt`` grid."""
    disturb(s, scenario)
    s.setup()
    assert s.PFlow.run(), "ANDES power flow did not converge"
    s.TDS.config.update(tf=scenario.duration, tstep=dt, fixt=1, shrinkt=0, no_tqdm=1)
    assert s.TDS.run(), f"ANDES could not simulate {scenario.name}"
    ts = s.dae.ts
    g = s.GENROU
    t = np.arange(int(round(scenario.duration / dt))) * dt

    def series(kind: str, var) -> np.ndarray:
        x = (ts.x if kind == "x" else ts.y)[:, var.a[0]]
        return np.interp(t, ts.t, x)

    out = {
        "v_t": series("y", s.Bus.v),  # the first bus is the machine's
        "theta_t": series("y", s.Bus.a),
        "omega": series("x", g.omega),
        "delta": series("x", g.delta),
        "v_f": series("y", g.vf),
        "p_m": series("y", g.tm) * TO_SYSTEM,
        "p_e": series("y", g.Pe) * TO_SYSTEM,
        "q_e": series("y", g.Qe) * TO_SYSTEM,
        "i_d": series("y", g.Id) * TO_SYSTEM,
        "i_q": series("y", g.Iq) * TO_SYSTEM,
    }
    return {"t": t, **out}


def write_set(
    folder: Path,
    record: Mapping[str, object],
    scenarios: Sequence[Scenario],
    *,
    seed: int = 0,
    noise: float = 1.0,
) -> Path:
    """Each scenario simulated by ANDES, sensor noise added (``noise`` x the simulator's), as a CSV set."""
    return noisy_set(
        folder,
        scenarios,
        lambda sc: run(system(record), sc),
        mva=MACHINE_MVA,
        source="andes",
        description="andes GENROU single machine, infinite bus",
        seed=seed,
        noise=noise,
    )


# A unit in closed loop for the MOD-026/027 tests: TABLE 1 with X'_q = X'_d = X'' (GENROU is then the
# fourth-order model), PSS/E's D 0 (phid's 0.8 at P_m0 0.8), SEXS and TGOV1. No comment line in the
# file: ANDES's .dyr reader does not take PSS/E's '@!' comments.
STAGED_UNIT = """1 'GENROU' 1  1.437 0.03 0.1351 0.03 3.48 0.0
   2.54 2.41 0.5 0.5 0.5 0.15 0.0 0.0 /
1 'SEXS' 1 0.2 5.0 100.0 0.05 -5.0 5.0 /
1 'TGOV1' 1 0.05 0.5 1.0 0.0 2.0 6.0 0.0 /
"""
# the staged tests: a grid voltage step, V_ref +0.02 pu, ANDES's TGOV1 auxiliary input +0.004
# (times 1/R: a valve step of 0.08 pu, short of V_MAX, which small-signal paths do not model)
STAGED_TESTS = [
    Scenario("grid_voltage_-5%", "voltage_step", 0.95, duration=8.0),
    Scenario("vref_step", "field_step", 0.02, duration=8.0),
    Scenario("load_ref_step", "torque_step", 0.004, duration=8.0),
]


def staged_config() -> SimulationConfig:
    from phid_ros.model.parameters import TABLE1

    return SimulationConfig(params=TABLE1.replace(X_q_prime=TABLE1.X_d_prime))


def run_unit(dyr: Path, scenario: Scenario) -> dict[str, np.ndarray]:
    """One staged test of the unit in ``dyr`` (2 ms steps)."""
    return run(system(dyr=dyr, cfg=staged_config()), scenario, dt=0.002)


def write_staged_unit(
    folder: Path, unit: str = STAGED_UNIT, tests: Sequence[Scenario] = STAGED_TESTS
) -> tuple[Path, Path]:
    """The unit's .dyr and its staged tests recorded with the simulator's sensor noise (a CSV set)."""
    folder.mkdir(parents=True, exist_ok=True)
    dyr = folder / "unit.dyr"
    dyr.write_text(unit)
    manifest = noisy_set(
        folder / "tests",
        tests,
        lambda sc: run_unit(dyr, sc),
        mva=MACHINE_MVA,
        source="andes",
        description="GENROU + SEXS + TGOV1, staged tests",
    )
    return dyr, manifest
