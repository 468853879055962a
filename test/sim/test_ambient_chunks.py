"""An ambient run in chunks is one run: the state, the wander and the steps carry over."""

from __future__ import annotations

import numpy as np

from phid_ros.sim.ambient import AmbientSettings, Drift, ambient_chunks, simulate_ambient
from phid_ros.sim.runner import SimulationConfig
from phid_ros.sim.sensors import SensorModel


def test_chunks_join_into_the_run_in_one_piece() -> None:
    # no wander (its random draws come in another order in chunks), steps and a drift across the chunk ends
    settings = AmbientSettings(
        duration_s=130.0, load_std=0.0, voltage_std=0.0, step_every_s=20.0, drifts=(Drift("H", 10.0, 120.0, 0.2),)
    )
    cfg = SimulationConfig(sensors=SensorModel(noiseless=True))
    whole = simulate_ambient(settings, cfg)
    chunks = list(ambient_chunks(settings, cfg, chunk_s=30.0))
    assert len(chunks) == 5 and [len(c.t) for c in chunks] == [30_000] * 4 + [10_001]
    t = np.concatenate([c.t for c in chunks])
    assert np.array_equal(t, whole.t)
    for name, x in whole.truth.items():
        assert np.allclose(np.concatenate([c.truth[name] for c in chunks]), x, rtol=0, atol=1e-12), name
    assert np.array_equal(np.concatenate([c.parameters["H"] for c in chunks]), whole.parameters["H"])


def test_the_wander_goes_on_across_a_chunk_end() -> None:
    settings = AmbientSettings(duration_s=60.0, step_every_s=1e6, load_std=0.02, load_tau_s=30.0)
    a, b, _ = ambient_chunks(settings, SimulationConfig(sensors=SensorModel(noiseless=True)), chunk_s=30.0)
    # an Ornstein-Uhlenbeck path 1 ms on: the chunks meet where one sample's step would take it
    step = abs(b.truth["p_m"][0] - a.truth["p_m"][-1])
    typical = np.median(np.abs(np.diff(a.truth["p_m"])))
    assert step < 10 * typical
