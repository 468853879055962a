"""The aligner: one grid from four streams, and every kind of bad input counted, never stored."""

import numpy as np
import pytest

from phid_ros.io.topics import STREAMS
from phid_ros.model.channels import CHANNELS
from phid_ros.stream.align import Aligner
from phid_ros.stream.levels import Level

MS = 1_000_000
COL = {c: i for i, c in enumerate(CHANNELS)}


def values(spec, t_ns):
    """Deterministic per-channel test signals: channel index + time in s."""
    return {c: 0.9 + 0.01 * COL[c] + 1e-3 * (t_ns / 1e9) for c in spec.channels}


def feed(al, t0, n, period=MS, skip=(), mutate=None):
    for spec in STREAMS:
        if spec.name in skip:
            continue
        t = t0 + np.arange(n, dtype=np.int64) * period
        arrays = values(spec, t)
        if mutate:
            mutate(spec.name, arrays)
        al.ingest(spec.name, t0, period, arrays)


def collect(blocks):
    t = np.concatenate([b.t_ns for b in blocks])
    x = np.concatenate([b.values for b in blocks])
    return t, x


def test_streams_on_one_clock_pass_through_exactly():
    al = Aligner()
    for k in range(5):
        feed(al, 10**9 + k * 100 * MS, 100)
    t, x = collect(al.pull(final=True))
    assert np.array_equal(t, 10**9 + np.arange(500) * MS)
    for c in CHANNELS:
        assert np.allclose(x[:, COL[c]], 0.9 + 0.01 * COL[c] + 1e-3 * t / 1e9, rtol=0, atol=1e-15)
    assert all(h.dropped == 0 and h.gaps == 0 for h in al.health.values())


def test_a_slower_offset_stream_is_interpolated():
    al = Aligner()
    feed(al, 0, 400, skip=("pmu",))
    # the PMU at 200 Hz, 2.5 ms off the grid: linear signals interpolate exactly
    t0 = 2_500_000
    t = t0 + np.arange(80, dtype=np.int64) * 5 * MS
    spec = next(s for s in STREAMS if s.name == "pmu")
    al.ingest("pmu", t0, 5 * MS, values(spec, t))
    t_out, x = collect(al.pull(final=True))
    inside = (t_out >= t[0]) & (t_out <= t[-1])
    expect = 0.9 + 0.01 * COL["delta"] + 1e-3 * t_out / 1e9
    assert np.allclose(x[inside, COL["delta"]], expect[inside], atol=1e-12)


def test_a_gap_gives_nan_and_is_counted():
    al = Aligner()
    feed(al, 0, 100)
    feed(al, 100 * MS, 100, skip=("encoder",))
    feed(al, 200 * MS, 100)
    t, x = collect(al.pull(final=True))
    gap = (t > 100 * MS) & (t < 199 * MS)
    assert np.isnan(x[gap, COL["omega"]]).all()
    assert np.isfinite(x[gap, COL["v_t"]]).all()
    assert al.health["encoder"].gaps == 1 and al.health["encoder"].gap_grid_points >= 95


@pytest.mark.parametrize(
    "bad, counter",
    [
        (
            lambda name, a: (
                a.__setitem__("v_t", np.where(np.arange(len(a["v_t"])) == 7, np.nan, a["v_t"]))
                if name == "pt_ct"
                else None
            ),
            "nonfinite",
        ),
        (
            lambda name, a: (
                a.__setitem__("omega", np.where(np.arange(len(a["omega"])) == 3, np.inf, a["omega"]))
                if name == "encoder"
                else None
            ),
            "nonfinite",
        ),
        (lambda name, a: a.__setitem__("v_t", a["v_t"] * 20.0) if name == "pt_ct" else None, "implausible"),  # kV feed
    ],
)
def test_bad_values_are_dropped_and_counted(bad, counter):
    al = Aligner()
    feed(al, 0, 100)
    feed(al, 100 * MS, 100, mutate=bad)
    feed(al, 200 * MS, 100)
    t, x = collect(al.pull(final=True))
    stream = "encoder" if "omega" in str(bad.__code__.co_consts) else "pt_ct"
    h = al.health[stream]
    assert getattr(h, counter) > 0 and h.dropped == getattr(h, counter)
    # what was accepted is untouched: every finite output equals the clean signal
    clean = 0.9 + 0.01 * np.arange(len(CHANNELS))[None, :] + 1e-3 * t[:, None] / 1e9
    ok = np.isfinite(x)
    assert np.allclose(x[ok], clean[ok], atol=1e-12)


def test_a_dead_channel_leaves_its_stream_s_live_channels_in_place():
    """omega with no finite value in a whole message: P_m of the same message is kept (a torque
    step stays visible), omega is a gap there, and the samples are counted, not dropped."""
    al = Aligner()
    feed(al, 0, 100)
    dead = lambda name, a: a.__setitem__("omega", np.full(len(a["omega"]), np.nan)) if name == "encoder" else None  # noqa: E731
    feed(al, 100 * MS, 100, mutate=dead)
    feed(al, 200 * MS, 100)
    t, x = collect(al.pull(final=True))
    h = al.health["encoder"]
    assert h.dead_channel == 100 and h.dropped == 0 and h.accepted == 300
    inside = (t >= 100 * MS) & (t < 200 * MS)
    assert np.isnan(x[inside, COL["omega"]]).all() and np.isfinite(x[inside, COL["p_m"]]).all()
    assert np.isfinite(x[~inside, COL["omega"]]).all()
    assert h.status(stream_now_ns=int(t[-1]))[0] == Level.WARN


def test_a_stream_that_never_starts_does_not_hold_the_others_back():
    """Every sample of the excitation stream NaN: the grid starts without it after stale_ns
    instead of keeping the other streams' samples until the end of the input."""
    al = Aligner()
    dead = lambda name, a: a.__setitem__("v_f", np.full(len(a["v_f"]), np.nan)) if name == "excitation" else None  # noqa: E731
    blocks = []
    for k in range(30):
        feed(al, k * 100 * MS, 100, mutate=dead)
        blocks += al.pull()
    t, x = collect(blocks)
    assert t.size >= 1900 and np.isnan(x[:, COL["v_f"]]).all() and np.isfinite(x[:, COL["v_t"]]).all()


def test_duplicates_and_out_of_order_are_dropped_and_told_apart():
    al = Aligner()
    feed(al, 0, 100)
    spec = next(s for s in STREAMS if s.name == "pt_ct")
    t = np.arange(50, 60, dtype=np.int64) * MS  # stamps already accepted, sent again: duplicates
    al.ingest("pt_ct", 50 * MS, MS, values(spec, t))
    t = np.arange(99, 109, dtype=np.int64) * MS  # first one duplicates the last accepted
    al.ingest("pt_ct", 99 * MS, MS, values(spec, t))
    h = al.health["pt_ct"]
    assert h.duplicates == 11 and h.out_of_order == 0 and h.accepted == 109
    # a block that skips ahead, then the skipped samples arrive late: out of order, not duplicates
    t = np.arange(120, 130, dtype=np.int64) * MS
    al.ingest("pt_ct", 120 * MS, MS, values(spec, t))
    t = np.arange(110, 115, dtype=np.int64) * MS
    al.ingest("pt_ct", 110 * MS, MS, values(spec, t))
    assert h.out_of_order == 5 and h.duplicates == 11 and h.accepted == 119


def test_conflicting_duplicates_keep_the_first_value():
    """Every 10th encoder block sent twice with another P_m: the second is dropped, never averaged."""
    al = Aligner()
    spec = next(s for s in STREAMS if s.name == "encoder")
    for k in range(20):
        feed(al, k * 100 * MS, 100)
        if k % 10 == 0:
            t = k * 100 * MS + np.arange(100, dtype=np.int64) * MS
            v = values(spec, t)
            v["p_m"] = v["p_m"] + 0.05
            al.ingest("encoder", int(t[0]), MS, v)
    t, x = collect(al.pull(final=True))
    assert al.health["encoder"].duplicates == 200 and al.health["encoder"].out_of_order == 0
    assert np.allclose(x[:, COL["p_m"]], 0.9 + 0.01 * COL["p_m"] + 1e-3 * t / 1e9, atol=1e-12)


def test_clock_jump_back_starts_a_new_segment():
    al = Aligner()
    feed(al, 100 * 10**9, 300)
    feed(al, 5 * 10**9, 300)  # simulated time reset / bag loop
    blocks = al.pull(final=True)
    segs = {b.segment for b in blocks}
    assert segs == {0, 1}
    t0 = np.concatenate([b.t_ns for b in blocks if b.segment == 0])
    t1 = np.concatenate([b.t_ns for b in blocks if b.segment == 1])
    assert t0.size == 300 and t1.size == 300 and t1[0] == 5 * 10**9
    assert sum(h.clock_jumps for h in al.health.values()) == 1 and al.segment == 1  # one event, counted once


def test_health_status_in_diagnostic_updater_style():
    al = Aligner()
    for k in range(10):
        feed(al, k * 100 * MS, 100)
    level, msg = al.health["pt_ct"].status()
    assert level == Level.OK and "1000 Hz" in msg
    slow = Aligner()
    for k in range(10):
        feed(slow, k * 100 * MS, 50, period=2 * MS)  # 500 Hz where 1 kHz is expected
    level, msg = slow.health["pmu"].status()
    assert level == Level.WARN and "rate 500 Hz" in msg
    assert al.health["pmu"].status(now_ns=10**12)[0] == Level.STALE or al.health["pmu"].last_receive_ns is None


def test_a_slower_stream_is_interpolated_between_its_own_samples_and_its_holes_stay_holes():
    """A 50 Hz PMU beside 1 kHz PT/CT: linear between its samples 20 ms apart (once NaN: five grid
    periods was the limit, so every window was stale); a hole of more than five of its own periods is a gap."""
    al = Aligner()
    t0 = 10**9
    for spec in STREAMS:
        period = 20 * MS if spec.name == "pmu" else MS
        n = 2000 // (period // MS)
        t = t0 + np.arange(n, dtype=np.int64) * period
        if spec.name == "pmu":
            keep = (t < t0 + 1000 * MS) | (t >= t0 + 1200 * MS)  # a 200 ms hole: ten of its periods
            arrays = {c: v[keep] for c, v in values(spec, t).items()}
            for a, b in ((0, int(keep[:50].sum())), (int(keep[:50].sum()), int(keep.sum()))):
                al.ingest("pmu", int(t[keep][a]), period, {c: v[a:b] for c, v in arrays.items()})
        else:
            al.ingest(spec.name, t0, period, values(spec, t))
    t, x = collect(al.pull(final=True))
    delta = x[:, COL["delta"]]
    inside = (t <= t0 + 980 * MS) | ((t >= t0 + 1200 * MS) & (t <= t0 + 1980 * MS))
    assert np.isfinite(delta[inside]).all()
    assert np.allclose(delta[inside], 0.9 + 0.01 * COL["delta"] + 1e-3 * t[inside] / 1e9, rtol=0, atol=1e-12)
    assert np.isnan(delta[(t > t0 + 980 * MS) & (t < t0 + 1200 * MS)]).all()
    assert al.health["pmu"].gaps == 1


def test_a_message_whose_arrays_differ_in_length_is_dropped_whole_and_counted():
    """A block with one short array (a truncated ROS message): no value of it is placed, a
    one-sample array is not broadcast over the block, and what came before is kept."""
    al = Aligner()
    feed(al, 0, 100)
    for short in (99, 1):
        feed(
            al,
            100 * MS,
            100,
            mutate=lambda name, a, k=short: a.__setitem__("i_q", a["i_q"][:k]) if name == "pt_ct" else None,
        )
    feed(al, 200 * MS, 100)
    t, x = collect(al.pull(final=True))
    h = al.health["pt_ct"]
    assert h.malformed == 200 and h.dropped == 200 and h.accepted == 200 and h.messages == 4
    hole = (t > 100 * MS) & (t < 199 * MS)
    assert hole.sum() == 98 and np.isnan(x[hole, COL["i_q"]]).all() and np.isnan(x[hole, COL["v_t"]]).all()
    clean = 0.9 + 0.01 * np.arange(len(CHANNELS))[None, :] + 1e-3 * t[:, None] / 1e9
    assert np.allclose(x[t < 100 * MS], clean[t < 100 * MS], atol=1e-12)
    assert "malformed 200" in al.status("pt_ct")[1]
