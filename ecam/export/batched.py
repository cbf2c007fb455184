"""numpy routines for many rows at once, to the bits of one call per row.

The vendor exports place points with ``np.linspace``, ``np.interp`` and ``np.mean`` on every
stretch of a cam between its joints; called once per stretch, Python's overhead grows with the
segments times the calls. These do the same arithmetic on all stretches together -- the very
operations numpy performs, in the same order -- so the exported files stay byte for byte what the
per-stretch calls gave (tests/test_export_vendor.py compares them with numpy's own functions).
"""

from __future__ import annotations

import numpy as np

__all__ = ["linspaces", "pairwise_sum", "interp_rows"]

# numpy's pairwise summation: at most this many elements are added in one unrolled block
# (numpy/_core/src/umath/loops_utils.h.src, PW_BLOCKSIZE) ...
_PAIRWISE_BLOCK = 128
# ... and larger ranges are split in two, the first half rounded down to a multiple of 8.
_PAIRWISE_UNROLL = 8


def linspaces(start, stop, counts):
    """``np.linspace(start[i], stop[i], counts[i] + 1)`` for every i, concatenated.

    numpy computes ``k * step + start`` with ``step = (stop - start) / count`` and sets the last
    point to ``stop`` (or, for a step that underflows to 0, ``k / count * (stop - start) + start``);
    so does this, element by element.

    Parameters
    ----------
    start, stop : array_like of float, shape (n,)
    counts : array_like of int, shape (n,)
        Intervals per row, at least 1.

    Returns
    -------
    nodes : ndarray, shape (sum(counts + 1),)
    row : ndarray of int
        The row of each node.
    last : ndarray of bool
        True at each row's last node (its ``stop``).
    """
    start, stop = np.asarray(start, dtype=float), np.asarray(stop, dtype=float)
    counts = np.asarray(counts, dtype=np.int64)
    row = np.repeat(np.arange(counts.size), counts + 1)
    first = np.cumsum(counts + 1) - (counts + 1)
    k = (np.arange(row.size) - first[row]).astype(float)
    delta = stop - start
    step = delta / counts
    nodes = k * step[row] + start[row]
    flat = step == 0.0
    if flat.any():
        at = flat[row]
        nodes[at] = k[at] / counts[row[at]] * delta[row[at]] + start[row[at]]
    last = np.zeros(row.size, dtype=bool)
    last[first + counts] = True
    nodes[last] = stop
    return nodes, row, last


def pairwise_sum(size: int, values, leaf: int = 1 << 20):
    """``np.add.reduce`` of a float64 array of ``size`` elements that is never held whole:
    ``values(begin, end)`` gives any slice of it. The ranges are split as numpy's pairwise
    summation splits them, and each range of at most ``leaf`` elements is summed by numpy, so the
    result has numpy's bits with at most ``leaf`` elements in memory at a time."""
    if size <= leaf or size <= _PAIRWISE_BLOCK:
        return np.add.reduce(values(0, size))

    def total(begin, count):
        if count <= leaf:
            return np.add.reduce(values(begin, begin + count))
        half = count // 2
        half -= half % _PAIRWISE_UNROLL
        return total(begin, half) + total(begin + half, count - half)

    return total(0, size)


def interp_rows(t, row, xp, fp):
    """``np.interp(t[i], xp[row[i]], fp[row[i]])`` for every i.

    Each row of ``xp`` must increase. numpy finds j with xp[j] <= t < xp[j + 1] and returns
    ``slope * (t - xp[j]) + fp[j]``, ``slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])`` (the
    other end's form where that is NaN), fp[j] where t equals xp[j], and the end values outside;
    so does this (numpy/_core/src/multiarray/compiled_base.c, arr_interp).
    """
    t = np.asarray(t, dtype=float)
    row = np.asarray(row, dtype=np.int64)
    width = xp.shape[1]
    # how many entries of its row are <= t: a bisection run on every t at once
    low = np.zeros(t.size, dtype=np.int64)
    high = np.full(t.size, width, dtype=np.int64)
    while True:
        active = low < high
        if not active.any():
            break
        middle = (low + high) // 2
        below = active & (xp[row, np.minimum(middle, width - 1)] <= t)
        low = np.where(below, middle + 1, low)
        high = np.where(active & ~below, middle, high)
    j = low - 1
    inner = (j >= 0) & (j < width - 1)
    jj = np.clip(j, 0, width - 2)
    x0, x1 = xp[row, jj], xp[row, jj + 1]
    y0, y1 = fp[row, jj], fp[row, jj + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (y1 - y0) / (x1 - x0)
        out = slope * (t - x0) + y0
        nan = np.isnan(out)
        if nan.any():
            out = np.where(nan, slope * (t - x1) + y1, out)
            out = np.where(np.isnan(out) & (y0 == y1), y0, out)
    out = np.where(inner & (x0 == t), y0, out)
    out = np.where(j < 0, fp[row, 0], out)
    out = np.where(j >= width - 1, fp[row, width - 1], out)
    return out
