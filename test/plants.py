"""What the independent plants (test/andes_plant.py, test/steps_plant.py) share: the sensor noise
added to their channels and the CSV scenario set written from their runs."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from phid_ros.io.csvset.csv_export import write_csv_set
from phid_ros.io.csvset.csv_import import ScenarioTable, recording_from_tables
from phid_ros.sim.scenarios import Scenario

# the simulator's sensor noise (phid_ros.sim.sensors defaults), per channel
NOISE = {"v_t": 0.002, "i_d": 0.003, "i_q": 0.003, "p_e": 0.003, "q_e": 0.003, "omega": 1e-5}
NOISE.update({"p_m": 0.002, "theta_t": 0.001, "delta": 0.001, "v_f": 0.005})


def noisy_set(
    folder: Path,
    scenarios: Sequence[Scenario],
    simulate: Callable[[Scenario], dict[str, np.ndarray]],
    *,
    mva: float,
    source: str,
    description: str,
    seed: int = 0,
    noise: float = 1.0,
) -> Path:
    """Each scenario through ``simulate`` (its channels and ``t``), sensor noise added (``noise``
    x the simulator's), as a CSV set; ``source`` prefixes each scenario's origin."""
    rng = np.random.default_rng(seed)
    tables = []
    for sc in scenarios:
        ch = simulate(sc)
        t = ch.pop("t")
        for c, x in ch.items():
            # a recorder's own channels (a stabiliser's output) come as the controller computed them
            ch[c] = x + noise * NOISE.get(c, 0.0) * rng.standard_normal(x.size)
        tables.append(
            ScenarioTable(sc.name, sc.kind, sc.role, sc.generator_damping, t, ch, sc.t_event, f"{source}:{sc.name}")
        )
    return write_csv_set(folder, recording_from_tables(tables, 50.0, mva, description))
