"""Measurements the diagnosis cannot weigh are refused, not diagnosed into invented effects."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from phid_ros.diagnose.options import DiagnoseError
from phid_ros.diagnose.workflow import diagnose
from phid_ros.model.parameters import TABLE1


def test_phasors_measured_over_a_window_are_refused(noisy_scenarios) -> None:
    windowed = [replace(s, measurement_window_s=0.02) for s in noisy_scenarios]
    with pytest.raises(DiagnoseError, match=r"measured over a 20 ms window"):
        diagnose(windowed, TABLE1.as_dict())


def test_a_channel_without_sample_noise_is_refused(noisy_scenarios) -> None:
    flat = []
    for s in noisy_scenarios:
        frame = replace(s.frame, values=s.frame.values.copy())
        frame.channel("omega")[:] = np.round(frame.channel("omega"), 2)  # quantised far below its noise
        flat.append(replace(s, frame=frame))
    with pytest.raises(DiagnoseError, match=r"channel\(s\) omega show no sample-to-sample noise"):
        diagnose(flat, TABLE1.as_dict())
