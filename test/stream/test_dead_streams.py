"""A dead sensor channel or stream loses no event: every disturbance is listed and stored, with
the reason its window is not usable."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from phid_ros.stream.detector import DetectorSettings
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
