"""A recorder's own channels beside the grid: kept as stamped, handed to each window on its stamps."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.model.conventions import NS
from phid_ros.stream.recorder import RecorderBuffer, on_stamps

PERIOD = 4_807_692  # 208 reports per second


def test_on_stamps_takes_the_sample_at_its_stamp_and_interpolates_only_across_one_period() -> None:
    ts = np.array([0, 10, 20, 50, 60], dtype=np.int64)
    x = np.array([1.0, 2.0, 3.0, 6.0, 7.0])
    out = on_stamps(ts, {"i_fd": x, "v_s": np.full(5, np.nan)}, 10, np.array([10, 15, 35, 60, 70], dtype=np.int64))
    assert set(out) == {"i_fd"}  # a channel the recorder did not keep is left out
    assert out["i_fd"][:2].tolist() == [2.0, 2.5] and out["i_fd"][3] == 7.0
    assert np.isnan(out["i_fd"][2]) and np.isnan(out["i_fd"][4])  # across a gap, after the end


def test_the_buffer_counts_what_it_refuses_and_hands_a_window_its_share() -> None:
    buf = RecorderBuffer(10.0)
    t0 = 1_700_000_000 * NS
    i_fd = np.linspace(0.5, 0.6, 416)
    for k in range(0, 416, 104):  # four messages of 0.5 s
        buf.ingest("field_controller", t0 + k * PERIOD, PERIOD, {"i_fd": i_fd[k : k + 104], "v_r": i_fd[k : k + 104]})
    h = buf.health["field_controller"]
    assert (h.messages, h.accepted, h.gaps) == (4, 416, 0)
    assert h.rate_hz() == pytest.approx(208.0, rel=1e-3)
    buf.ingest("field_controller", t0, PERIOD, {"i_fd": i_fd[:10], "v_r": i_fd[:10]})  # already taken
    assert h.out_of_order == 10 and h.accepted == 416
    later = t0 + 500 * PERIOD  # 84 reports lost
    buf.ingest("field_controller", later, PERIOD, {"i_fd": np.ones(10), "v_r": np.ones(10)})
    assert (h.gaps, h.missing) == (1, 84)
    window = t0 + np.arange(100, 120, dtype=np.int64) * PERIOD + PERIOD // 2  # between reports
    share = buf.columns(window)
    assert set(share) == {"i_fd", "v_r"}
    assert share["i_fd"] == pytest.approx((i_fd[100:120] + i_fd[101:121]) / 2)
    across = buf.columns(t0 + np.array([410, 450], dtype=np.int64) * PERIOD)
    assert across["i_fd"][0] == pytest.approx(i_fd[410]) and np.isnan(across["i_fd"][1])  # the hole is a hole
    buf.ingest("field_controller", t0, PERIOD, {"i_fd": np.ones(3), "v_r": np.ones(2)})
    assert h.malformed == 3
