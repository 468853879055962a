"""The shipped bags are what bags/regenerate.sh says they are."""

from pathlib import Path

import numpy as np

from phid_ros.io.bags.recordings import read_recording
from phid_ros.io.files.results import read_json
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.recording import recording_from_runs
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import validation_scenarios
from phid_ros.sim.sensors import DEFAULT_CHANNEL_SENSORS, SensorModel

BAGS = Path(__file__).resolve().parents[1] / "bags"


def test_catalogue_bag_holds_the_paper_catalogue():
    rec = read_recording(BAGS / "catalogue")
    assert len(rec.scenarios) == 18
    assert sum(s.role == "identify" for s in rec.scenarios) == 15
    assert all(len(s) == 660_000 for s in rec.streams.values())
    truth = read_json(BAGS / "catalogue.truth.json")
    assert truth["parameters"] == TABLE1.as_dict()
    assert sum(p.stat().st_size for p in BAGS.rglob("*") if p.is_file()) < 30e6


def test_validation_mcap_regenerates_to_within_one_lsb():
    shipped = read_recording(BAGS / "validation.mcap")
    cfg = SimulationConfig(sensors=SensorModel(seed=1))
    fresh = recording_from_runs(simulate_scenarios(validation_scenarios(), cfg), cfg)
    for name, stream in fresh.streams.items():
        assert np.array_equal(stream.t_ns, shipped.streams[name].t_ns)
        for c, values in stream.channels.items():
            # quantised samples may differ by one LSB if libm rounds a last bit differently
            assert np.max(np.abs(values - shipped.streams[name].channels[c])) <= DEFAULT_CHANNEL_SENSORS[c].lsb
