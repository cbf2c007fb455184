"""Vendor exports of cams with many segments (issue 14): the cost grows with the segments, not with
their square, and the files are the very bytes the per-segment code wrote.

Costs are counted, not timed: Python lines executed (``sys.settrace``), which also count the
iterations of a loop that calls nothing, and calls of the cam. The per-segment code each batched
routine replaced is kept here as the oracle its results must equal bit for bit.
"""

import math
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ecam
from conftest import CAMS
from ecam.export import export_cam
from ecam.export.batched import interp_rows, linspaces, pairwise_sum
from ecam.export.certify import (
    _SAMPLE_MARGIN, Cam, Hermite, _jump_costs, _psi_cost, equidistributed, interval_bounds, knot_data,
)
from ecam.export import stretches as stretches_module
from ecam.export.stretches import _settle_loop, settle
from ecam.export.twincat_cnc import LIMIT, MIN_POINTS, MIN_SPACING, entry_counts
from ecam.table import divisors
from test_profile import many_segments

SHIPPED = ("combination_drrd", "modified_sine", "rotary_knife")


class OverBudget(Exception):
    pass


def python_lines(work, budget=None):
    """Python lines ``work()`` executes (every frame, numpy's Python included); with a ``budget``,
    stops it with OverBudget as soon as it passes that many, so a cost gone quadratic fails fast."""
    count = 0

    def local(frame, event, arg):
        nonlocal count
        if event == "line":
            count += 1
            if budget is not None and count > budget:
                raise OverBudget(count)
        return local

    previous = sys.gettrace()
    sys.settrace(lambda frame, event, arg: local)
    try:
        work()
    finally:
        sys.settrace(previous)
    return count


def shipped(stem):
    return ecam.load_cam(CAMS / f"{stem}.toml")


# -- the oracles: the per-segment code this replaced ------------------------------------------------
def envelope_by_piece(cam, order):
    """Cam._envelope as it was: each piece between breaks on its own."""
    cuts = sorted({0.0, cam.period, *(b for b, _, _ in cam.profile.breaks() if 0.0 < b < cam.period)})
    width = cam.period / 2**14
    lefts, rights, cells = [], [], []
    for p0, p1 in zip(cuts[:-1], cuts[1:]):
        count = max(16, math.ceil((p1 - p0) / width))
        nodes = np.linspace(p0, p1, count + 1)
        inner = nodes[:-1]
        values = np.abs(np.concatenate([cam(inner, order, "right"), cam(nodes[-1:], order, "left")]))
        slopes = np.abs(np.concatenate([cam(inner, order + 1, "right"), cam(nodes[-1:], order + 1, "left")]))
        step = (p1 - p0) / count
        cells.append(np.maximum(values[:-1], values[1:]) + slopes.max() * step / 2 * _SAMPLE_MARGIN)
        lefts.append(nodes[:-1])
        rights.append(nodes[1:])
    return np.concatenate(lefts), np.concatenate(rights), np.concatenate(cells)


def jump_costs_by_jump(cam, hermite):
    """interval_bounds' jump term as it was: every jump of the cam, one at a time."""
    n = hermite.degree
    a, b = hermite.x[:-1], hermite.x[1:]
    h = b - a
    jumps = np.zeros(a.size)
    for where, order, size in cam.jumps:
        if order > n:
            continue
        i = int(np.searchsorted(hermite.x, where, side="right")) - 1
        if 0 <= i < a.size and a[i] < where < b[i]:
            jumps[i] += abs(size) * h[i] ** order * _psi_cost(n, order, round(float((where - a[i]) / h[i]), 12))
    return jumps


def equidistributed_by_stretch(cam, intervals, order, forced, grid, floor=1e-3, end_intervals=1):
    """equidistributed as it was: each stretch weighed and split on its own, every call."""
    forced = sorted(set(forced))
    pieces = []
    for lo, hi in zip(forced[:-1], forced[1:]):
        x = np.linspace(lo, hi, 4097)
        mid = (x[:-1] + x[1:]) / 2
        pieces.append((x, np.abs(cam(mid, order, "right")) ** (1.0 / order)))
    everything = np.concatenate([d for _, d in pieces])
    added = floor * float(everything.mean()) if everything.max() > 0 else 1.0
    weights = [np.diff(x) * (density + added) for x, density in pieces]
    totals = np.array([w.sum() for w in weights])
    base = np.ones(len(pieces), dtype=int)
    base[0] = max(base[0], end_intervals)
    base[-1] = max(base[-1], end_intervals)
    total = max(intervals, int(base.sum()))
    desired = totals / totals.sum() * total
    counts = _settle_loop(np.maximum(base, np.floor(desired).astype(int)), base, desired, total)
    knots = []
    for (x, _), cell, count in zip(pieces, weights, counts):
        cumulative = np.concatenate([[0.0], np.cumsum(cell)])
        knots.extend(np.interp(np.linspace(0.0, cumulative[-1], count + 1), cumulative, x))
    return np.unique(np.round(np.array(knots) / cam.period * grid).astype(np.int64))


def cams_to_compare():
    return [Cam(shipped(stem)) for stem in SHIPPED] + [Cam(many_segments(40), master_counts=40 * 64)]


# -- the same numbers ---------------------------------------------------------------------------------
def test_the_batched_numpy_routines_give_numpys_bits():
    rng = np.random.default_rng(14)
    rows, width = 60, 4097
    start = np.sort(rng.random(rows) * 1e3)
    stop = start + rng.random(rows) * 10.0 ** rng.integers(-6, 3, rows)
    counts = rng.integers(1, 40, rows)
    nodes, row, last = linspaces(start, stop, counts)
    assert np.array_equal(nodes, np.concatenate([np.linspace(a, b, c + 1) for a, b, c in zip(start, stop, counts)]))
    assert np.array_equal(row, np.repeat(np.arange(rows), counts + 1)) and last.sum() == rows
    tiny, _, _ = linspaces([0.0, 1.0], [1e-320, 2.0], [4096, 3])  # numpy's branch for a step that underflows
    assert np.array_equal(tiny, np.concatenate([np.linspace(0.0, 1e-320, 4097), np.linspace(1.0, 2.0, 4)]))

    xp = np.concatenate([np.zeros((rows, 1)), np.cumsum(rng.random((rows, width - 1)), axis=1)], axis=1)
    fp = np.linspace(start, stop, width, axis=1)
    t, row, _ = linspaces(np.full(rows, -1.0), xp[:, -1] + 1.0, counts)  # ends outside, on and between
    t = np.concatenate([t, xp[3, ::97]])
    row = np.concatenate([row, np.full(xp[3, ::97].size, 3)])
    assert np.array_equal(interp_rows(t, row, xp, fp), [np.interp(u, xp[r], fp[r]) for u, r in zip(t, row)])

    values = rng.random(3_000_003) * 10.0 ** rng.integers(-8, 8, 3_000_003)
    assert pairwise_sum(values.size, lambda b, e: values[b:e], leaf=4099) == np.add.reduce(values)
    assert pairwise_sum(values.size, lambda b, e: values[b:e]) / values.size == values.mean()


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 50.0), st.integers(1, 3)), min_size=1, max_size=40),
       st.integers(-30, 30))
def test_settling_the_counts_at_once_is_the_loop(pieces, change):
    """Largest remainder, both ways, ties to the first: the sorted steps equal the step-by-step loop
    (a surplus over the bases or a shortfall, shares with equal remainders)."""
    desired = np.array([share for share, _ in pieces])
    base = np.array([b for _, b in pieces])
    counts = np.maximum(base, np.floor(desired).astype(int))
    total = max(int(base.sum()), int(counts.sum()) + change)
    assert np.array_equal(settle(counts, base, desired, total), _settle_loop(counts, base, desired, total))


def test_settling_many_equal_shares_is_the_loop():
    desired = np.full(500, 0.25)
    base = np.ones(500, dtype=int)
    base[0] = base[-1] = 2
    for total in (502, 600, 1000):
        counts = np.maximum(base, np.floor(desired * total / 125).astype(int))
        assert np.array_equal(settle(counts, base, desired * total / 125, total),
                              _settle_loop(counts, base, desired * total / 125, total))


@pytest.mark.parametrize("order", [1, 2])
def test_the_envelope_is_the_piece_by_piece_one(order):
    for cam in cams_to_compare():
        left, right, table = cam._envelope(order)
        expected = envelope_by_piece(cam, order)
        assert np.array_equal(left, expected[0]) and np.array_equal(right, expected[1])
        assert np.array_equal(table[0], expected[2])


def test_the_jump_term_is_the_jump_by_jump_one():
    """Equally spaced knots put the cams' jumps inside intervals, several in one at 7 knots."""
    charged = 0
    for cam in cams_to_compare():
        for degree in (1, 3, 5):
            for count in (7, 60, 301):
                x = np.linspace(0.0, cam.period, count)
                hermite = Hermite.continuous(x, degree, knot_data(cam, x, (degree + 1) // 2))
                expected = jump_costs_by_jump(cam, hermite)
                assert np.array_equal(_jump_costs(cam, degree, x[:-1], x[1:], np.diff(x)), expected)
                charged += np.count_nonzero(expected)
    assert charged > 100


@pytest.mark.parametrize("kept", [True, False])
def test_spreading_gives_the_stretch_by_stretch_knots(kept, monkeypatch):
    """The weights computed once and the knots of all stretches at once are the per-stretch loop's,
    whether the cumulative weights are kept or recomputed (a cam with too many stretches)."""
    if not kept:
        monkeypatch.setattr(stretches_module, "_KEPT", 0)
    for cam in cams_to_compare():
        grid = cam.master_counts
        for order, floor, ends, forced in ((2, 1e-3, 1, cam.breaks(5)), (4, 0.25, 2, cam.breaks(3)),
                                           (6, 1e-3, 1, cam.breaks(5))):
            for intervals in (len(forced), len(forced) + 3, 97, 400):
                assert np.array_equal(equidistributed(cam, intervals, order, forced, grid, floor, ends),
                                      equidistributed_by_stretch(cam, intervals, order, forced, grid, floor, ends))


def test_the_greedy_search_asks_in_batches_for_the_same_numbers(monkeypatch):
    """greedy_knots with batched bounds places the knots it places one bound at a time, and every
    batched bound is the single one to the bit."""
    from ecam.export import certify

    seen = {"calls": 0}
    original = certify.greedy_knots

    def spy(bound, grid, forced, budget, *, bounds, **options):
        seen["one by one"] = original(bound, grid, forced, budget, **options)

        def checked(i, js):
            values = bounds(i, js)
            for j, value in list(zip(js.tolist(), values.tolist()))[::5]:
                assert value == bound(i, j)
            seen["calls"] += 1
            return values

        seen["batched"] = original(bound, grid, forced, budget, bounds=checked, **options)
        return seen["batched"]

    monkeypatch.setattr(certify, "greedy_knots", spy)
    result = export_cam(many_segments(24), "csv", tolerance=0.002, interp="cubic", master_counts=24 * 64)
    assert seen["batched"] == seen["one by one"] and len(seen["batched"]) == result.points
    assert seen["calls"] < 2 * result.points  # about one batch per knot, not one call per probe


# -- the costs ----------------------------------------------------------------------------------------
def test_one_intervals_bound_costs_the_same_on_a_cam_of_any_size():
    """The greedy placement weighs thousands of intervals: one interval's bound must not read every
    jump of the cam (it did, which made csv and codesys exports quadratic in the segments)."""
    costs = []
    for segments in (32, 512):
        cam = Cam(many_segments(segments))
        x = np.array([1.25, 1.5])  # inside the first rise, no jump inside
        data = knot_data(cam, x, 2)
        hermite = Hermite.continuous(x, 3, data)
        interval_bounds(cam, hermite)  # envelopes built
        costs.append(python_lines(lambda: interval_bounds(cam, hermite)))
    assert costs[1] == costs[0], costs


def test_the_envelope_evaluates_the_cam_four_times_per_order(monkeypatch):
    calls = []
    original = Cam.__call__

    def counting(self, master, order=0, side="right"):
        calls.append(np.size(master))
        return original(self, master, order, side)

    monkeypatch.setattr(Cam, "__call__", counting)
    cam = Cam(many_segments(256))
    calls.clear()
    cam._envelope(2)
    assert len(calls) == 4  # values and slopes, from the right inside and from the left at the ends


def test_spreading_weighs_the_cam_once_for_every_count(monkeypatch):
    """Kollmorgen tries one point count after another: the cam is evaluated for the first only."""
    calls = []
    original = Cam.__call__

    def counting(self, master, order=0, side="right"):
        calls.append(np.size(master))
        return original(self, master, order, side)

    monkeypatch.setattr(Cam, "__call__", counting)
    cam = Cam(many_segments(64))
    forced = cam.breaks(3)
    equidistributed(cam, 100, 4, forced, cam.master_counts, 0.25, 2)
    assert calls
    calls.clear()
    for intervals in range(101, 160, 7):
        equidistributed(cam, intervals, 4, forced, cam.master_counts, 0.25, 2)
    assert calls == []


def test_isg_entry_counts_try_only_the_table_sizes():
    """The ISG table holds 2..360 entries: a master range of 10^16 x 1e-4 deg is tried against
    those, not factored (10^8 trial divisions, 18 s)."""
    for grid in (2000, 3_600_000, 2**20 * 3**5, 10**7 + 19, 7 * 11 * 13 * 1000):
        assert entry_counts(grid) == [n for n in divisors(grid) if MIN_POINTS <= n <= LIMIT
                                      and grid // n >= MIN_SPACING]
    found = []
    python_lines(lambda: found.append(entry_counts(10**16)), budget=20 * LIMIT)
    assert found[0][:6] == [2, 4, 5, 8, 10, 16] and found[0][-1] == 320


@pytest.mark.slow
@pytest.mark.parametrize("fmt, interp", [("codesys", None), ("csv", "linear"), ("csv", "cubic")])
def test_an_export_costs_lines_in_proportion_to_the_segments(fmt, interp):
    """Four times the segments, less than 4.5 times the Python lines (2.5 to 3.5 measured); before
    issue 14 the formats that place points freely ran 5.5 to 6.8 times as many (every interval the
    greedy search weighed read every jump of the cam). Kollmorgen's search over the point count is
    held by test_spreading_weighs_the_cam_once_for_every_count; the formats with equally spaced
    points share the bound held by test_one_intervals_bound_costs_the_same_on_a_cam_of_any_size."""
    lines = []
    for segments in (32, 128):
        profile = many_segments(segments)
        lines.append(python_lines(lambda: export_cam(profile, fmt, tolerance=0.01, interp=interp)))
    assert lines[1] / lines[0] < 4.5, lines
