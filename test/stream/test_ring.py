import numpy as np
import pytest

from phid_ros.stream.ring import RingBuffer


def block(t0, n, c=2):
    t = np.arange(t0, t0 + n, dtype=np.int64)
    return t, np.column_stack([t * 1.0 + k for k in range(c)])


def test_append_wraps_and_keeps_the_newest():
    rb = RingBuffer(10, ("a", "b"))
    for t0 in range(0, 37, 7):
        rb.append(*block(t0, 7))
    t, x = rb.rows(0, len(rb))
    assert len(rb) == 10 and rb.total_written == 42
    assert list(t) == list(range(32, 42))
    assert np.array_equal(x[:, 1], t + 1.0)
    assert rb.latest_ns == 41 and rb.oldest_ns == 32


def test_window_by_time_is_a_view_when_contiguous():
    rb = RingBuffer(100, ("a",))
    rb.append(*block(0, 60, 1))
    t, x = rb.window(10, 19)
    assert list(t) == list(range(10, 20))
    assert np.shares_memory(x, rb._x)
    rb.append(*block(60, 60, 1))  # wraps
    t, x = rb.window(55, 70)
    assert list(t) == list(range(55, 71))


def test_a_block_larger_than_the_capacity_keeps_its_tail():
    rb = RingBuffer(5, ("a",))
    rb.append(*block(0, 12, 1))
    assert list(rb.stamps()) == [7, 8, 9, 10, 11]


def test_capacity_must_be_positive():
    with pytest.raises(ValueError):
        RingBuffer(0, ("a",))
