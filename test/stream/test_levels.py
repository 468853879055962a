"""Levels as one type, merged by max as diagnostic_updater merges them."""

from __future__ import annotations

from phid_ros.stream.align import StreamHealth
from phid_ros.stream.levels import Level, worst


def test_levels_are_diagnostic_msgs_bytes_merged_by_max_and_said_by_name() -> None:
    assert [int(v) for v in Level] == [0, 1, 2, 3]  # DiagnosticStatus.OK, WARN, ERROR, STALE
    assert worst() is Level.OK and worst(Level.WARN, Level.OK) is Level.WARN
    assert worst(Level.ERROR, Level.STALE, Level.WARN) is Level.STALE
    assert f"{Level.WARN}" == str(Level.WARN) == "WARN" and f"{Level.ERROR:>6}" == " ERROR"


def test_a_stream_s_problems_merge_to_the_worst_not_the_last() -> None:
    """A dead channel on a few samples is a WARN; more than half the samples dropped is an ERROR,
    whatever was judged before it: each problem raises the level, none lowers it."""
    h = StreamHealth("pt_ct", expected_rate_hz=1000.0)
    h.samples, h.dead_channel, h.last_stamp_ns = 100, 10, 1
    assert h.status()[0] is Level.WARN
    h.duplicates = 60
    assert h.status()[0] is Level.ERROR
