"""Run scenarios on the plant and pass the true signals through the sensors.

Each scenario becomes a segment: the disturbance at ``t_event``, the analysis
window up to ``duration`` (the paper's 30 s), then a *restore* period in which
the disturbed input ramps back to its pre-event value and holds, so the plant
returns to the operating point and the next scenario can follow it in one
continuous recording with no jump (the restore ramps are far too slow to look
like a disturbance).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ
from phid_ros.model.parameters import TABLE1, GeneratorParameters
from phid_ros.sim.network import Network
from phid_ros.sim.plant import Inputs, OperatingPoint, Plant, SteadyState
from phid_ros.sim.scenarios import Scenario
from phid_ros.sim.sensors import SensorModel

Array = NDArray[np.float64]

# Loss of synchronism shows as a speed excursion far beyond any stable swing.
MAX_SPEED_DEVIATION = 0.05


@dataclass(frozen=True)
class SimulationConfig:
    params: GeneratorParameters = TABLE1
    network: Network = field(default_factory=Network)
    operating_point: OperatingPoint = field(default_factory=OperatingPoint)
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ
    dt: float = 1e-3
    sensors: SensorModel = field(default_factory=SensorModel)
    restore_ramp: float = 5.0
    restore_hold: float = 5.0
    effects: tuple = ()  # PlantEffect instances (phid_ros.sim.effects), none by default

    def plant(self) -> Plant:
        return Plant(self.params, self.network, f_nominal_hz=self.f_nominal_hz, effects=self.effects)


@dataclass(frozen=True)
class ScenarioRun:
    scenario: Scenario
    t: Array  # s from segment start, uniform with step dt
    truth: dict[str, Array]  # true sensor channels
    states: dict[str, Array]  # delta, omega, e_q, e_d
    measured: dict[str, Array]  # sensor outputs
    steady_state: SteadyState

    @property
    def n_analysis(self) -> int:
        """Samples that belong to the scenario proper (before the restore period)."""
        return int(round(self.scenario.duration / (self.t[1] - self.t[0])))


def _segment_steps(scenario: Scenario, cfg: SimulationConfig) -> int:
    return int(round((scenario.duration + cfg.restore_ramp + cfg.restore_hold) / cfg.dt))


def build_inputs(scenarios: Sequence[Scenario], plant: Plant, ss: SteadyState, cfg: SimulationConfig) -> Inputs:
    """Per-step input arrays (n_steps, n_scenarios) for a batch of scenarios."""
    n = len(scenarios)
    n_steps = max(_segment_steps(sc, cfg) for sc in scenarios)
    dt = cfg.dt
    p_m = np.full((n_steps, n), ss.p_m)
    v_inf = np.full((n_steps, n), ss.v_inf)
    v_f = np.full((n_steps, n), ss.v_f)
    z_f = np.full((n_steps, n), np.nan, dtype=complex)
    k_ramp = int(round(cfg.restore_ramp / dt))
    for j, sc in enumerate(scenarios):
        k_ev = int(round(sc.t_event / dt))
        k_end = int(round(sc.duration / dt))
        ramp = 1.0 - np.arange(1, k_ramp + 1) / max(k_ramp, 1)
        if sc.kind == "torque_step":
            p_m[k_ev:k_end, j] += sc.magnitude
            p_m[k_end : k_end + k_ramp, j] += sc.magnitude * ramp[: max(0, min(k_ramp, n_steps - k_end))]
        elif sc.kind in ("voltage_step", "field_step"):
            x, x0 = (v_inf, ss.v_inf) if sc.kind == "voltage_step" else (v_f, ss.v_f)
            dv = x0 * (sc.magnitude - 1.0)
            x[k_ev:k_end, j] += dv
            x[k_end : k_end + k_ramp, j] += dv * ramp[: max(0, min(k_ramp, n_steps - k_end))]
        else:
            k_clear = int(round((sc.t_event + sc.magnitude) / dt))
            z_f[k_ev:k_clear, j] = 1j * sc.fault_reactance
    v_th, z_th = plant.network.thevenin(v_inf, z_f)
    damping = np.array([plant.params.D if sc.generator_damping else 0.0 for sc in scenarios])
    return Inputs(
        p_m=p_m,
        v_f=v_f,
        v_th_abs=np.abs(v_th),
        v_th_angle=np.angle(v_th),
        r_th=z_th.real,
        x_th=z_th.imag,
        damping=damping,
    )


def simulate_scenarios(
    scenarios: Sequence[Scenario], cfg: SimulationConfig | None = None, *, seed_offset: int = 0
) -> list[ScenarioRun]:
    """Simulate all scenarios in one vectorised run; sensor noise is seeded per scenario index."""
    cfg = cfg or SimulationConfig()
    if not scenarios:
        raise SimulationError("no scenarios to simulate")
    plant = cfg.plant()
    ss = plant.steady_state(cfg.operating_point)
    inputs = build_inputs(scenarios, plant, ss, cfg)
    x0 = np.repeat(ss.x[:, None], len(scenarios), axis=1)
    traj = plant.simulate(x0, inputs, cfg.dt)
    runs: list[ScenarioRun] = []
    channels = traj.channels()
    for j, sc in enumerate(scenarios):
        n = _segment_steps(sc, cfg)
        dev = np.max(np.abs(traj.omega[:n, j] - 1.0))
        if dev > MAX_SPEED_DEVIATION:
            raise SimulationError(
                f"scenario {sc.name} loses synchronism (speed deviation {dev:.3f} pu); "
                "reduce the disturbance or the loading"
            )
        truth = {k: v[:n, j].copy() for k, v in channels.items()}
        states = {k: getattr(traj, k)[:n, j].copy() for k in ("delta", "omega", "e_q", "e_d")}
        measured = cfg.sensors.measure(truth, stream_seed=seed_offset + j)
        for effect in cfg.effects:
            measured = effect.on_measurements(measured, cfg.dt)
        runs.append(ScenarioRun(sc, traj.t[:n].copy(), truth, states, measured, ss))
    return runs
