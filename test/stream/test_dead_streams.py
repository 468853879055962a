"""A dead sensor channel or stream loses no event: every disturbance is listed and stored, with
the reason its window is not usable."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from phid_ros.stream.detector import DetectorSettings
from phid_ros.stream.levels import Level
from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
from phid_ros.stream.replay import replay


def _run(rec, tmp_path, name):
    settings = PipelineSettings(
        detector=DetectorSettings(pre_s=1.0, post_s=3.0), auto_recalibrate=False, store_path=str(tmp_path / name)
    )
    p = MonitorPipeline(settings)
    out = replay(rec, p)
    stored = {w.event.event_id: w.reason for w in p.store.all()}
    p.close()
    return out, stored


@pytest.mark.parametrize("channel", ["v_f", "omega", "delta"])
def test_every_event_is_listed_and_stored_with_a_dead_channel(short_recording, tmp_path, channel):
    clean, _ = _run(short_recording, tmp_path, "clean.sqlite")
    rec = copy.deepcopy(short_recording)
    for s in rec.streams.values():
        if channel in s.channels:
            s.channels[channel][:] = np.nan
    out, stored = _run(rec, tmp_path, "dead.sqlite")
    assert len(clean.events) >= 3
    assert [(e.kind, e.inception_ns) for e in out.events] == [(e.kind, e.inception_ns) for e in clean.events]
    assert len(out.windows) == len(clean.windows)
    for w in out.windows:
        assert not w.usable and f"no data on {channel} (a dead channel)" in w.reason
    assert set(stored) == {e.event_id for e in clean.events}  # stored, with the reason
    assert all(f"no data on {channel}" in reason for reason in stored.values())


def test_a_channel_declared_not_recorded_is_absent_not_dead(short_recording, tmp_path):
    """A trend log has no rotor angle, speed or P_m: declared not recorded (the import's metadata),
    their NaN is no dead channel, the encoder stream is "not recorded here", and the windows are used."""
    rec = copy.deepcopy(short_recording)
    for s in rec.streams.values():
        for c in ("omega", "p_m", "delta"):
            if c in s.channels:
                s.channels[c][:] = np.nan
    settings = PipelineSettings(
        detector=DetectorSettings(pre_s=1.0, post_s=3.0),
        auto_recalibrate=False,
        store_path=str(tmp_path / "declared.sqlite"),
        not_recorded=frozenset({"omega", "p_m", "delta"}),
    )
    p = MonitorPipeline(settings)
    out = replay(rec, p)
    assert out.windows and all(w.usable for w in out.windows), [w.reason for w in out.windows]
    assert p.aligner.status("encoder") == (Level.OK, "not recorded here (declared)")
    assert p.health["pmu"].dead_channel == 0 and p.health["encoder"].dropped == 0
    p.close()


def test_a_deployment_declares_what_its_recorder_never_carries() -> None:
    from phid_ros.stream.params import INGEST, pipeline_settings, validate

    s = pipeline_settings({"not_recorded": "omega, delta,p_m"}, detect=True)
    assert s.not_recorded == {"omega", "delta", "p_m"} and s.detector.not_recorded == s.not_recorded
    assert validate(INGEST, "not_recorded", "omega,speed", running=False) == (
        "not_recorded: unknown channel(s) speed; channels: v_t, theta_t, i_d, i_q, omega, delta, v_f, p_m, p_e, q_e"
    )
    assert validate(INGEST, "not_recorded", "omega", running=True) is not None  # set at start, not while running
