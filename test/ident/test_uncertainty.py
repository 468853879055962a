"""The cluster-robust covariance: its block sums are np.add.at's, bit for bit."""

from __future__ import annotations

import numpy as np

from phid_ros.ident.uncertainty import block_ids, cluster_robust_cov


def _sandwich_by_add_at(x: np.ndarray, r: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    xtx_inv = np.linalg.pinv(x.T @ x)
    n_blocks = int(blocks.max()) + 1
    sums = np.zeros((n_blocks, x.shape[1]))
    np.add.at(sums, blocks, x * r[:, None])
    p = x.shape[1]
    return n_blocks / max(n_blocks - p, 1) * xtx_inv @ (sums.T @ sums) @ xtx_inv


def test_block_sums_are_add_ats_in_any_block_order():
    rng = np.random.default_rng(7)
    x, r = rng.standard_normal((5000, 3)), rng.standard_normal(5000)
    for blocks in (block_ids([1200, 3800], 250), rng.integers(0, 37, 5000)):  # contiguous, and scattered
        assert np.array_equal(cluster_robust_cov(x, r, blocks), _sandwich_by_add_at(x, r, blocks))


def test_blocks_never_span_segments():
    ids = block_ids([5, 0, 3], 2)
    assert ids.tolist() == [0, 0, 1, 1, 2, 3, 3, 4]
