"""Recordings that look like the field's, written from the project's own simulator.

- :func:`trend_log_set`: an excitation controller's trend logs of commissioning tests: a
  ``date`` column (DD.MM.YYYY) and a time-of-day column, about 208 reports per second with
  jitter, each report the controller's measurement averaged over its interval, V_t in kV, P in
  MW, Q in Mvar, I_t in A, E_fd in V and I_fd in A on the controller's own bases (not the
  machine's), one no-load field step and on-line field and grid steps. No rotor angle, speed
  or P_m.
- :func:`pmu_set`: PMU exports of disturbances (V and I phasors, frequency), no field, no angle.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from phid_ros.model.conventions import dq_to_terminal
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.sim.effects.magnetic_saturation import saturation_curve, saturation_factor
from phid_ros.sim.network import Network
from phid_ros.sim.plant import OperatingPoint
from phid_ros.sim.runner import ScenarioRun, SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario

KV, MVA = 20.0, 1000.0
V_BASE = KV * 1e3 / np.sqrt(3)
I_BASE = MVA * 1e6 / (np.sqrt(3) * KV * 1e3)
FIELD_BASE_V = 123.4  # V of E_fd at 1 pu (air-gap line): the controller does not know it
FIELD_BASE_A = 1876.0  # A of I_fd at 1 pu
TREND_PERIOD = 1 / 208.0
# an open circuit: the breaker open, the machine's current through a megohm of reactance
NO_LOAD = SimulationConfig(network=Network(x_transformer=1e6), operating_point=OperatingPoint(0.0, 1.0, 0.0))

TREND_MAP = """
machine: {mva: 1000, kv: 20, f_nominal_hz: 50}
time: Time
date: Date
channels:
  v_t: {name: UT, unit: kV_ll}
  p_e: {name: P, unit: MW}
  q_e: {name: Q, unit: Mvar}
  i_t: {name: IT, unit: A}
  v_f: {name: UF, unit: V}
  i_fd: {name: IF, unit: A}
scenarios:
"""

PMU_MAP = """
machine: {mva: 1000, kv: 20, f_nominal_hz: 50}
time: Timestamp
channels:
  v_t: {name: "GEN:V1_MAG", unit: V}
  theta_t: {name: "GEN:V1_ANG", unit: deg}
  i_t: {name: "GEN:I1_MAG", unit: A}
  phi_i: {name: "GEN:I1_ANG", unit: deg}
scenarios:
"""


def field_current(
    run: ScenarioRun, params: GeneratorParameters, saturation: tuple[float, float] | None = None
) -> np.ndarray:
    """X_ad I_fd of the fourth-order model (7): E'_q + (X_d - X'_d) i_d, E_fd at every steady state,
    and S(E'_q) E'_q more on a saturated machine (GENSAL's form, the quadratic curve through
    ``saturation`` = (S(1.0), S(1.2)))."""
    e_q = run.states["e_q"]
    out = e_q + (params.X_d - params.X_d_prime) * run.truth["i_d"]
    if saturation is not None:
        a, b = saturation_curve("quadratic", *saturation)
        out = out + saturation_factor(False, a, b, e_q) * e_q
    return out


def _trend_rows(
    run: ScenarioRun, rng: np.random.Generator, day: str, t0: float, params: GeneratorParameters
) -> list[str]:
    m = run.measured
    n = run.n_analysis
    t_sim = run.t[:n]
    # the controller samples on its own clock and stamps each report up to 0.3 ms off it
    t = np.arange(0.0, t_sim[-1] - 1e-3, TREND_PERIOD)
    t[1:] += rng.uniform(-3e-4, 3e-4, len(t) - 1)

    def at(x: np.ndarray) -> np.ndarray:
        # the controller reports its measurement averaged over the report interval (five of the
        # simulator's 1 ms samples), not one noisy instant
        padded = np.concatenate((np.full(2, x[0]), x[:n], np.full(2, x[n - 1])))
        return np.interp(t, t_sim, np.convolve(padded, np.full(5, 0.2), mode="valid"))

    v, p, q = at(m["v_t"]), at(m["p_e"]), at(m["q_e"])
    cols = {
        "UT": v * KV,
        "P": p * MVA,
        "Q": q * MVA,
        "IT": np.hypot(p, q) / v * I_BASE,
        "UF": at(m["v_f"]) * FIELD_BASE_V,
        "IF": at(field_current(run, params)) * FIELD_BASE_A,
    }
    rows = []
    for k, tk in enumerate(t):
        s = t0 + tk
        clock = f"{int(s // 3600):02d}:{int(s % 3600 // 60):02d}:{s % 60:010.7f}"
        rows.append(";".join([day, clock, *(f"{cols[c][k]:.6f}".replace(".", ",") for c in cols)]))
    return rows


def trend_log_set(
    folder: Path, params: GeneratorParameters, seed: int = 0, exciter: Mapping[str, float] | None = None
) -> tuple[list[Path], Path]:
    """A no-load field step, four on-line field steps and two grid voltage steps as trend logs, and their map.

    ``exciter`` (SEXS constants): on line, E_fd is that SEXS's answer to the true V_t and to a
    V_ref step of 0.01 pu per field step's 5 % (the simulator's own E_fd is held but for its
    steps), the sensor noise added as before; the no-load test keeps the simulator's, so the
    field base is still calibrated on the air-gap line."""
    rng = np.random.default_rng(seed)
    no_load = simulate_scenarios([Scenario("noload", "field_step", 1.1, duration=15.0)], _cfg(NO_LOAD, params))
    online = simulate_scenarios(
        [Scenario(f"step_{k}", "field_step", m, duration=20.0) for k, m in enumerate((1.05, 0.95, 1.10, 0.90))]
        + [Scenario(f"grid_{k}", "voltage_step", m, duration=20.0) for k, m in enumerate((1.10, 0.90))],
        _cfg(SimulationConfig(), params),
        seed_offset=1 + 10 * seed,
    )
    if exciter is not None:
        online = [_with_exciter(run, exciter) for run in online]
    paths = []
    entries = []
    for run, day, t0 in [(no_load[0], "20.09.2015", 12 * 3600 + 52 * 60 + 35.236463)] + [
        (r, "21.09.2015", 9 * 3600 + k * 600.0) for k, r in enumerate(online)
    ]:
        header = "Date;Time;" + ";".join(("UT", "P", "Q", "IT", "UF", "IF"))
        path = folder / f"{run.scenario.name}.csv"
        path.write_text("\n".join([header, *_trend_rows(run, rng, day, t0, params)]) + "\n", encoding="utf-8")
        paths.append(path)
        entries.append(f"  {run.scenario.name}: {{kind: {run.scenario.kind}, event_time_s: {run.scenario.t_event}}}")
    cmap = folder / "map.yaml"
    cmap.write_text(TREND_MAP + "\n".join(entries) + "\n")
    return paths, cmap


def pmu_set(folder: Path, params: GeneratorParameters, seed: int = 0) -> tuple[list[Path], Path]:
    """Faults and load steps as PMU exports at 100 reports per second: V and I phasors only."""
    del seed  # the simulator's sensor noise is seeded per scenario
    scs = [Scenario(f"fault_{k}", "fault", tf, duration=12.0) for k, tf in enumerate((0.08, 0.12, 0.15))]
    scs += [Scenario(f"load_{k}", "torque_step", dp, duration=12.0) for k, dp in enumerate((0.1, -0.1))]
    runs = simulate_scenarios(scs, _cfg(SimulationConfig(), params))
    paths, entries = [], []
    step = 10
    for run in runs:
        m = {c: x[: run.n_analysis : step] for c, x in run.measured.items()}
        lines = pmu_lines(phasor_columns(m, step, "GEN"))
        path = folder / f"{run.scenario.name}.csv"
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
        entries.append(f"  {run.scenario.name}: {{kind: {run.scenario.kind}, event_time_s: {run.scenario.t_event}}}")
    cmap = folder / "map.yaml"
    cmap.write_text(PMU_MAP + "\n".join(entries) + "\n")
    return paths, cmap


def phasor_columns(m: dict[str, np.ndarray], step: int, pmu: str) -> dict[str, object]:
    """A PMU's columns from simulated channels taken every ``step`` ms: ISO stamps, V and I
    phasors (angles wrapped to +-180 degrees, as PMUs report) and the terminal frequency."""
    i_mag, i_ang = dq_to_terminal(m["i_d"], m["i_q"], m["delta"])
    t0 = np.datetime64("2026-03-04T05:06:07.000000000")
    return {
        "Timestamp": [str(t0 + np.timedelta64(int(k * step * 1e6), "ns")) for k in range(len(m["v_t"]))],
        f"{pmu}:V1_MAG": m["v_t"] * V_BASE,
        f"{pmu}:V1_ANG": np.degrees(np.angle(np.exp(1j * m["theta_t"]))),
        f"{pmu}:I1_MAG": i_mag * I_BASE,
        f"{pmu}:I1_ANG": np.degrees(np.angle(np.exp(1j * i_ang))),
        f"{pmu}:FREQ": 50.0 * (1 + np.gradient(np.unwrap(m["theta_t"]), step * 1e-3) / (2 * np.pi * 50)),
    }


def pmu_lines(cols: dict[str, object]) -> list[str]:
    """The export's lines: a header, then one report per row."""
    return [",".join(cols)] + [
        ",".join(v if isinstance(v, str) else repr(float(v)) for v in row) for row in zip(*cols.values())
    ]


def _with_exciter(run: ScenarioRun, values: Mapping[str, float]) -> ScenarioRun:
    from dataclasses import replace

    from phid_ros.controls.models import SEXS, ControlInputs

    n = len(run.t)
    k = int(np.searchsorted(run.t, run.scenario.t_event))
    v_t = run.truth["v_t"] - np.mean(run.truth["v_t"][:k])
    step = (np.arange(n) >= k).astype(float)
    reference = 0.2 * (run.scenario.magnitude - 1.0) if run.scenario.kind == "field_step" else 0.0
    inputs = ControlInputs(float(run.t[1] - run.t[0]), v_t, 0 * v_t, step)
    e_fd = float(np.mean(run.truth["v_f"][:k])) + SEXS().response(values, inputs, reference)
    noise = run.measured["v_f"] - run.truth["v_f"]
    return replace(run, truth={**run.truth, "v_f": e_fd}, measured={**run.measured, "v_f": e_fd + noise})


def _cfg(cfg: SimulationConfig, params: GeneratorParameters) -> SimulationConfig:
    from dataclasses import replace

    return replace(cfg, params=params)


def build_up_log(
    path: Path,
    t_d0: float,
    *,
    saturation: tuple[float, float] = (0.1, 0.4),
    seed: int = 0,
    dt: float = 0.096,
    rotor_circuit: tuple[float, float] | None = None,
) -> None:
    """A black start's soft-start build-up as an excitation controller's fast recorder writes it
    (Zakucac's: 96 ms, V_t in kV line to line, U_f in V, I_f in A): the open-circuit machine from
    its remanence (0.03 pu) under a set-point ramp 0.09 -> 1.0 pu over 7 s, the regulator's output
    at its ceiling (3 pu of E_fd) until V_t meets the ramp, then a PI holding it. No load, no
    dampers: T'_d0 dE/dt = E_fd - E (1 + S(E)) (GENSAL's d axis at I_d = 0), X_ad I_fd = E (1 + S(E)),
    V_t = E; the field's resistance and bases are the controller's (0.0969 ohm, I_fg 700 A).

    ``rotor_circuit`` (tau, T_k): the rotor's other circuits (dampers, the poles' iron) as one,
    which a rising flux drives (T_k di_k/dt + i_k = -tau dE/dt) and whose current the field's
    makes up: X_ad I_fd = E (1 + S(E)) - i_k, so the field current on the way up lies above the
    open-circuit curve by tau dE/dt, and decays onto it at the top in about T_k (Zakucac's
    build-ups: 855 A at 16 kV on the rise, 795 A three seconds later)."""
    rng = np.random.default_rng(seed)
    a, b = saturation_curve("quadratic", *saturation)
    h = 1e-3
    n = int(round(130.0 / h))
    e, x_i, i_k = 0.03, 0.0, 0.0
    tau_k, t_k = rotor_circuit or (0.0, 1.0)
    i_fg, r_f = 700.0, 0.0969
    rows = []
    every = int(round(dt / h))
    for k in range(n):
        t = k * h
        ref = 0.09 if t < 5.0 else min(1.0, 0.09 + (t - 5.0) * 0.91 / 7.0)
        if t < 5.0:
            e_fd = 0.0
        else:
            err = ref - e
            x_i += 2.0 * err * h
            e_fd = min(3.0, max(0.0, 20.0 * err + x_i + e * (1 + saturation_factor(False, a, b, e))))
        flux = e * (1 + saturation_factor(False, a, b, e)) - i_k  # X_ad I_fd
        if k % every == 0:
            u_f = e_fd * i_fg * r_f  # E_fd 1 pu drives I_fg through R_f
            v = (e + 2e-4 * rng.standard_normal()) * 16.0
            u_f, i_f = u_f + 0.2 * rng.standard_normal(), flux * i_fg + 0.3 * rng.standard_normal()
            rows.append(f"{t:.3f},{v:.5f},{u_f:.4f},{i_f:.3f}")
        de = (e_fd - flux) / t_d0
        i_k += h * (-tau_k * de - i_k) / t_k
        e += h * de
    path.write_text("t_s,Ug_kV,Uf_V,If_A\n" + "\n".join(rows) + "\n")
