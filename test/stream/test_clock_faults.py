"""Clock faults on a recorded bag: replay feeds messages in recording order and the aligner
handles jumps both ways with bounded memory; wild and zero stamps are dropped and counted."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from phid_ros.io.bags.recordings import read_recording, write_messages
from phid_ros.io.recording import ns_to_time, recording_messages
from phid_ros.model.conventions import NS, stamp_ns
from phid_ros.stream.detector import DetectorSettings
from phid_ros.stream.levels import Level
from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings
from phid_ros.stream.replay import replay


def _settings() -> PipelineSettings:
    # short windows so the 6 s scenarios of the fixture each give a complete one
    return PipelineSettings(detector=DetectorSettings(pre_s=1.0, post_s=3.0), auto_recalibrate=False)


def _restamp(msg, shift_ns: int):
    header = dataclasses.replace(msg.header, stamp=ns_to_time(stamp_ns(msg.header.stamp) + shift_ns))
    return dataclasses.replace(msg, header=header)


def _bag(tmp_path, rec, edit):
    """The recording as a single MCAP whose log times stay as recorded while ``edit`` changes stamps."""
    msgs = [edit(i, log, topic, typ, msg) for i, (log, topic, typ, msg) in enumerate(recording_messages(rec))]
    path = tmp_path / "faulty.mcap"
    write_messages(path, [(log, topic, typ, msg) for log, topic, typ, msg in msgs if msg is not None])
    return read_recording(path)


def _run(rec):
    p = MonitorPipeline(_settings())
    out = replay(rec, p)
    p.close()
    return p, out


@pytest.fixture(scope="module")
def clean(short_recording):
    return _run(short_recording)


def _faults(out):
    return [e for e in out.events if e.kind == "fault"]


def test_a_clock_jumping_back_starts_a_segment_and_the_later_fault_is_found(tmp_path, short_recording, clean):
    start, _ = short_recording.span_ns()
    jump_at = start + 10 * NS  # after the torque and voltage scenarios, before the fault
    back = 35 * NS

    def edit(i, log, topic, typ, msg):
        if hasattr(msg, "sample_period") and stamp_ns(msg.header.stamp) >= jump_at:
            return log, topic, typ, _restamp(msg, -back)
        return log, topic, typ, msg

    p, out = _run(_bag(tmp_path, short_recording, edit))
    assert sum(h.clock_jumps for h in p.health.values()) == 1
    assert all(h.out_of_order == 0 and h.dropped == 0 for h in p.health.values())
    [fault] = _faults(clean[1])
    [after] = _faults(out)
    assert after.inception_ns == fault.inception_ns - back  # found, at the same sample, on the new clock
    assert after.segment == 1


def test_a_single_wild_stamp_a_day_ahead_is_dropped_and_counted(tmp_path, short_recording, clean):
    target = None
    start, _ = short_recording.span_ns()

    def edit(i, log, topic, typ, msg):
        nonlocal target
        if topic.endswith("/pt_ct") and target is None and stamp_ns(msg.header.stamp) >= start + 5 * NS:
            target = i
            return log, topic, typ, _restamp(msg, 86_400 * NS)
        return log, topic, typ, msg

    rec = _bag(tmp_path, short_recording, edit)
    p, out = _run(rec)  # the old aligner allocated a day-long grid here (6.4 GiB) and crashed
    h = p.health["pt_ct"]
    assert h.wild_stamps == 100 and h.clock_jumps == 0 and h.out_of_order == 0
    assert [(e.kind, e.inception_ns) for e in out.events] == [(e.kind, e.inception_ns) for e in clean[1].events]


def test_a_clock_jumping_a_day_ahead_starts_a_segment_with_bounded_memory(tmp_path, short_recording, clean):
    start, _ = short_recording.span_ns()
    jump_at = start + 10 * NS

    def edit(i, log, topic, typ, msg):
        if hasattr(msg, "sample_period") and stamp_ns(msg.header.stamp) >= jump_at:
            return log, topic, typ, _restamp(msg, 86_400 * NS)
        return log, topic, typ, msg

    p, out = _run(_bag(tmp_path, short_recording, edit))
    assert sum(h.clock_jumps for h in p.health.values()) == 1
    [fault] = _faults(clean[1])
    [after] = _faults(out)
    assert after.inception_ns == fault.inception_ns + 86_400 * NS


def test_zero_stamps_are_counted_as_such_and_cost_only_the_windows_over_them(tmp_path, short_recording, clean):
    start, _ = short_recording.span_ns()

    def edit(i, log, topic, typ, msg):
        # two seconds of the excitation stream with an unset clock
        t = stamp_ns(msg.header.stamp) if hasattr(msg, "sample_period") else 0
        if topic.endswith("/excitation") and start + 5 * NS <= t < start + 7 * NS:
            return log, topic, typ, _restamp(msg, -t)
        return log, topic, typ, msg

    p, out = _run(_bag(tmp_path, short_recording, edit))
    h = p.health["excitation"]
    assert h.zero_stamps == 2000 and h.duplicates == 0 and h.out_of_order == 0 and h.clock_jumps == 0
    assert sum(h.clock_jumps for h in p.health.values()) == 0
    # windows clear of the two seconds are as without the fault; those over them miss excitation data
    lo, hi = start + 5 * NS, start + 7 * NS
    for w, c in zip(out.windows, clean[1].windows, strict=True):
        assert w.event.inception_ns == c.event.inception_ns and c.usable
        overlaps = w.t_ns[0] < hi and w.t_ns[-1] >= lo
        assert w.usable == (not overlaps), w.reason
        if overlaps:
            assert "v_f" in w.reason


def test_zero_stamps_through_the_python_api_are_not_a_clock_jump():
    from phid_ros.stream.align import Aligner

    al = Aligner()
    t0 = 1_767_225_600 * NS
    for k in range(30):
        for name, chans in (("pt_ct", 5), ("encoder", 2), ("pmu", 2), ("excitation", 1)):
            from phid_ros.io.topics import STREAMS_BY_NAME

            arrays = {c: np.full(100, 0.9) for c in STREAMS_BY_NAME[name].channels}
            stamp = 0 if (name == "encoder" and 10 <= k < 12) else t0 + k * 100_000_000
            al.ingest(name, stamp, 1_000_000, arrays)
    blocks = al.pull(final=True)
    assert {b.segment for b in blocks} == {0}
    assert al.health["encoder"].zero_stamps == 200 and al.health["encoder"].clock_jumps == 0


def test_a_stream_that_stops_is_stale_on_stream_time(tmp_path, short_recording):
    start, _ = short_recording.span_ns()

    def edit(i, log, topic, typ, msg):
        if topic.endswith("/excitation") and stamp_ns(msg.header.stamp) >= start + 8 * NS:
            return log, topic, typ, None  # the excitation feed ends at 8 s
        return log, topic, typ, msg

    p, _ = _run(_bag(tmp_path, short_recording, edit))
    level, message = p.aligner.status("excitation")
    assert level == Level.STALE and "stream time" in message
    assert p.aligner.status("pt_ct")[0] == Level.OK


def test_runs_a_stream_and_one_message_at_a_time_give_the_same_outputs(tmp_path, short_recording):
    """Unpaced, replay feeds a step's messages as one run a stream where the aligner can promise
    the same result; paced, one by one. On a bag with every fault at once both must agree."""
    start, _ = short_recording.span_ns()
    seen: dict[str, int] = {}

    def edit(i, log, topic, typ, msg):
        if not hasattr(msg, "sample_period"):
            return log, topic, typ, msg
        t = stamp_ns(msg.header.stamp)
        k = seen[topic] = seen.get(topic, 0) + 1
        if topic.endswith("/pt_ct") and k == 31:
            return log, topic, typ, _restamp(msg, 86_400 * NS)  # a wild stamp
        if topic.endswith("/pt_ct") and k in (40, 41):
            return log, topic, typ, None  # two messages lost: a gap
        if topic.endswith("/encoder") and k == 52:
            return log, topic, typ, dataclasses.replace(msg, omega=np.full(len(msg.omega), np.nan))  # non-finite
        if topic.endswith("/pmu") and k == 60:
            return log, topic, typ, dataclasses.replace(msg, delta=np.full(len(msg.delta), 2e6))  # implausible
        if topic.endswith("/excitation") and k in (70, 71):
            return log, topic, typ, _restamp(msg, -t)  # unset clock
        if topic.endswith("/excitation") and k == 80:
            return log, topic, typ, _restamp(msg, -100_000_000)  # a duplicate of the one before
        if t >= start + 10 * NS:
            return log, topic, typ, _restamp(msg, -35 * NS)  # every clock jumps back at 10 s
        return log, topic, typ, msg

    rec = _bag(tmp_path, short_recording, edit)
    results = []
    for rate in (None, 1e12):  # 1e12 x real time: paced, so one message at a time, and never waits
        p = MonitorPipeline(_settings())
        out = replay(rec, p, rate=rate)
        p.close()
        health = {n: dataclasses.asdict(h) for n, h in p.health.items()}
        windows = [(w.event.event_id, w.usable, w.reason, w.t_ns.tobytes(), w.values.tobytes()) for w in out.windows]
        results.append((health, [(e.kind, e.inception_ns, e.segment) for e in out.events], windows, p.samples_in))
    runs, one_by_one = results
    h = runs[0]
    assert h["pt_ct"]["wild_stamps"] == 100 and h["pt_ct"]["gaps"] >= 1 and h["encoder"]["dead_channel"] == 100
    assert h["pmu"]["implausible"] == 100 and h["excitation"]["zero_stamps"] == 200
    assert h["excitation"]["duplicates"] == 100 and sum(x["clock_jumps"] for x in h.values()) == 1
    assert runs == one_by_one
