"""Simulated scenarios -> one continuous recording (+ the truth that made it)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from typing import Any

import numpy as np

from phid_ros import __version__
from phid_ros.io.recording import Recording, ScenarioInfo, StreamSamples
from phid_ros.io.topics import STREAMS
from phid_ros.model.conventions import NS
from phid_ros.sim.runner import ScenarioRun, SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario

BASE_MVA = 1000  # the paper's machine: 1000 MVA, 20 kV
DEFAULT_START_NS = 1_767_225_600 * NS  # 2026-01-01T00:00:00Z: a plausible wall clock, fixed for determinism


def recording_from_runs(
    runs: Sequence[ScenarioRun], cfg: SimulationConfig, *, start_ns: int = DEFAULT_START_NS
) -> Recording:
    """Concatenate scenario segments back to back into one stream per sensor."""
    dt_ns = int(round(cfg.dt * NS))
    cursor = start_ns
    stamps: list[np.ndarray] = []
    channels: dict[str, list[np.ndarray]] = {}
    scenarios: list[ScenarioInfo] = []
    for run in runs:
        n = len(run.t)
        t_ns = cursor + np.arange(n, dtype=np.int64) * dt_ns
        stamps.append(t_ns)
        for name, values in run.measured.items():
            channels.setdefault(name, []).append(values)
        sc = run.scenario
        k_ev = int(round(sc.t_event / cfg.dt))
        clearing = 0 if sc.t_clear is None else int(t_ns[int(round(sc.t_clear / cfg.dt))])
        scenarios.append(
            ScenarioInfo(
                name=sc.name,
                kind=sc.kind,
                role=sc.role,
                generator_damping=sc.generator_damping,
                magnitude=sc.magnitude,
                start_ns=int(t_ns[0]),
                event_ns=int(t_ns[k_ev]),
                clearing_ns=clearing,
                end_ns=int(t_ns[run.n_analysis - 1]),
                description=sc.description,
            )
        )
        cursor = int(t_ns[-1]) + dt_ns
    t_all = np.concatenate(stamps)
    streams = {
        spec.name: StreamSamples(t_all.copy(), dt_ns, {c: np.concatenate(channels[c]) for c in spec.channels})
        for spec in STREAMS
    }
    return Recording(streams=streams, scenarios=scenarios, metadata=recording_metadata(cfg))


def recording_metadata(cfg: SimulationConfig) -> dict[str, str]:
    return {
        "f_nominal_hz": str(cfg.f_nominal_hz),
        "base_mva": str(BASE_MVA),
        "source": f"phid simulate (phid_ros {__version__})",
        "sensor_seed": str(cfg.sensors.seed),
    }


def truth_document(cfg: SimulationConfig, scenarios: Sequence[Scenario]) -> dict[str, Any]:
    """Everything needed to regenerate and to judge: parameters, plant, sensors, scenarios."""
    return {
        "parameters": cfg.params.as_dict(),
        "f_nominal_hz": cfg.f_nominal_hz,
        "base_mva": BASE_MVA,
        "network": asdict(cfg.network),
        "operating_point": asdict(cfg.operating_point),
        "dt": cfg.dt,
        "sensors": {
            "seed": cfg.sensors.seed,
            "noiseless": cfg.sensors.noiseless,
            "channels": {k: asdict(v) for k, v in cfg.sensors.channels.items()},
        },
        "scenarios": [asdict(s) for s in scenarios],
        "effects": [e.as_dict() for e in cfg.effects],
    }


def simulate_recording(scenarios: Sequence[Scenario], cfg: SimulationConfig) -> Recording:
    return recording_from_runs(simulate_scenarios(scenarios, cfg), cfg)
