"""Knots spread by the error density: the cam between its forced knots, each stretch weighed once.

:func:`ecam.export.certify.equidistributed` places a given number of intervals where
|d^order y/dx^order|^(1/order) is large. Its weights -- 4096 cells per stretch between forced knots
(the joints), each the cell's width times the density at its middle plus a floor -- depend on the
cam, the order, the forced knots and the floor, not on the number of intervals. The placement is
searched over many interval counts (Kollmorgen tries one after another, a tolerance bisects), so a
:class:`Stretches` computes them once, for all stretches in one pass, and each count then costs
its sharing out (:func:`settle`) and one interpolation for every knot at once.

The arithmetic is numpy's, per stretch, in the same order (:mod:`.batched`): the knots are those
of the per-stretch loop this replaces, to the bit.
"""

from __future__ import annotations

import numpy as np

from .batched import interp_rows, linspaces, pairwise_sum

__all__ = ["Stretches", "settle", "FINE"]

FINE = 4096  # cells per stretch
# Rows of cumulative weights kept between calls (FINE + 1 floats each): 2^24 floats, 128 MB, about
# 4000 stretches. A cam with more stretches recomputes the rows a count needs.
_KEPT = 2**24
_BLOCK = max(1, 2**20 // (FINE + 1))  # rows computed at once: a bounded working set


class Stretches:
    """The stretches of a cam between ``forced`` knots, weighed for spreading knots by the density
    of derivative ``order`` with ``floor`` times its mean added (see ``equidistributed``).

    Parameters
    ----------
    cam : callable
        ``cam(master, order, side)`` (an :class:`ecam.export.certify.Cam`), with ``period``.
    order : int
        At least 1.
    forced : sequence of float
        Sorted, distinct master positions, 0 and the period included.
    floor : float
        Fraction of the mean density added everywhere.
    """

    def __init__(self, cam, order: int, forced, floor: float) -> None:
        self.cam = cam
        self.order = order
        self.low = np.array(forced[:-1], dtype=float)
        self.high = np.array(forced[1:], dtype=float)
        rows = self.low.size
        keep = rows * (FINE + 1) <= _KEPT
        # the density's mean over every cell of every stretch, summed as np.mean sums one array
        largest = [0.0]
        density = np.empty(rows * FINE) if keep else None  # kept for the weights, when it fits

        def density_slice(begin, end):
            first, last = begin // FINE, (end - 1) // FINE + 1
            values = self._density(np.arange(first, last)).ravel()[begin - first * FINE:end - first * FINE]
            largest[0] = max(largest[0], float(values.max()))
            if keep:
                density[begin:end] = values
            return values

        mean = pairwise_sum(rows * FINE, density_slice) / (rows * FINE)
        self.added = floor * float(mean) if largest[0] > 0 else 1.0
        self.totals = np.empty(rows)     # each stretch's weight, summed as ndarray.sum sums it
        self.cum_last = np.empty(rows)   # and accumulated (the cumulative weight's last entry)
        self.first_knot = np.empty(rows)  # np.interp of 0 on the stretch: its start
        self._cumulative = np.empty((rows, FINE + 1)) if keep else None
        for first in range(0, rows, _BLOCK):
            block = np.arange(first, min(rows, first + _BLOCK))
            known = None if density is None else density[block[0] * FINE:(block[-1] + 1) * FINE].reshape(-1, FINE)
            x, cumulative, totals = self._weights(block, known)
            self.totals[block] = totals
            self.cum_last[block] = cumulative[:, -1]
            self.first_knot[block] = interp_rows(np.zeros(block.size), np.arange(block.size), cumulative, x)
            if keep:
                self._cumulative[block] = cumulative

    def _nodes(self, rows: np.ndarray) -> np.ndarray:
        """``np.linspace(low, high, FINE + 1)`` of the given stretches, one row each."""
        nodes, _, _ = linspaces(self.low[rows], self.high[rows], np.full(rows.size, FINE))
        return nodes.reshape(rows.size, FINE + 1)

    def _density(self, rows: np.ndarray) -> np.ndarray:
        """|d^order y/dx^order|^(1/order) at the middle of every cell of the given stretches."""
        x = self._nodes(rows)
        middle = (x[:, :-1] + x[:, 1:]) / 2
        return np.abs(self.cam(middle.ravel(), self.order, "right")).reshape(middle.shape) ** (1.0 / self.order)

    def _weights(self, rows: np.ndarray, density=None):
        """Nodes, cumulative weights (0 first) and total weights of the given stretches (their
        ``density`` when it is known)."""
        x = self._nodes(rows)
        cell = np.diff(x, axis=1) * ((self._density(rows) if density is None else density) + self.added)
        cumulative = np.concatenate([np.zeros((rows.size, 1)), np.cumsum(cell, axis=1)], axis=1)
        return x, cumulative, cell.sum(axis=1)

    def knots(self, counts: np.ndarray) -> np.ndarray:
        """Master positions of the knots when stretch i gets ``counts[i]`` intervals: per stretch,
        ``np.interp(np.linspace(0, W, counts[i] + 1), cumulative weight, x)`` (W its total), all
        concatenated (an end shared by two stretches appears twice)."""
        counts = np.asarray(counts, dtype=np.int64)
        targets, row, last = linspaces(np.zeros(counts.size), self.cum_last, counts)
        first = np.concatenate([[True], last[:-1]])
        out = np.where(first, self.first_knot[row], self.high[row])  # W interpolates to x[-1]
        inner = np.flatnonzero(~first & ~last)
        rows = np.unique(row[inner])
        for begin in range(0, rows.size, _BLOCK):
            block = rows[begin:begin + _BLOCK]
            if self._cumulative is not None:
                x, cumulative = self._nodes(block), self._cumulative[block]
            else:
                x, cumulative, _ = self._weights(block)
            here = inner[(row[inner] >= block[0]) & (row[inner] <= block[-1])]
            out[here] = interp_rows(targets[here], np.searchsorted(block, row[here]), cumulative, x)
        return out


def settle(counts: np.ndarray, base: np.ndarray, desired: np.ndarray, total: int) -> np.ndarray:
    """Largest remainder both ways: while the counts add up to more than ``total``, take one from
    the count furthest above its share ``desired`` among those above their ``base``; while less,
    give one to the count furthest below its share; ties to the first. Returns the settled counts.

    Taken one at a time, that costs the surplus times the counts. Instead every step the loop could
    take is listed with the value the loop would compare it by (a count's k-th step: its value after
    k steps) and the list is sorted once, by value, then position, then k: the loop's order, since
    each count's values only fall from one step to its next. A count's list is cut after about
    surplus / counts + 2 steps, more than it can reach; were a cut list ever used up, the loop
    itself runs instead.
    """
    surplus = int(counts.sum()) - total
    if surplus == 0:
        return counts.copy()
    if surplus > 0:
        pieces = np.flatnonzero(counts > base)
        reach = (counts - base)[pieces]
        listed = np.minimum(reach, (surplus - 1) // max(1, pieces.size) + 2)
        step = _first_steps(pieces, listed, reach, surplus, lambda piece, k: (counts[piece] - k) - desired[piece])
        sign = -1
    else:
        surplus = -surplus
        pieces = np.arange(counts.size)
        listed = np.full(counts.size, min(surplus, (surplus - 1) // counts.size + 2 + int(base.max())))
        reach = np.full(counts.size, surplus)
        step = _first_steps(pieces, listed, reach, surplus, lambda piece, k: desired[piece] - (counts[piece] + k))
        sign = 1
    if step is None:
        return _settle_loop(counts, base, desired, total)
    settled = counts.copy()
    np.add.at(settled, step, sign)
    return settled


def _first_steps(pieces, listed, reach, steps: int, value):
    """The piece of each of the loop's first ``steps`` steps, from each piece's first ``listed``
    steps (of the ``reach`` it has); None when a piece listed short of its reach used them all."""
    piece = np.repeat(pieces, listed)
    k = np.arange(piece.size) - np.repeat(np.cumsum(listed) - listed, listed)
    order = np.lexsort((k, piece, -value(piece, k)))[:steps]
    used = np.bincount(np.searchsorted(pieces, piece[order]), minlength=pieces.size)
    if order.size < steps or np.any((used >= listed) & (listed < reach)):
        return None
    return piece[order]


def _settle_loop(counts, base, desired, total):
    """The loop :func:`settle` stands for, one step at a time."""
    counts = counts.copy()
    while counts.sum() > total:
        over = np.where(counts > base, counts - desired, -np.inf)
        counts[int(np.argmax(over))] -= 1
    while counts.sum() < total:
        counts[int(np.argmax(desired - counts))] += 1
    return counts
