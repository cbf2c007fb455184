"""`ecam plot` (ecam.plot.plot_profile): what the figure shows, and that its cost grows with the
segments plus the samples, not with their product (issue 14: 140 s at 4000 segments, one
matplotlib object per segment, joint and label).

The figure is taken before it is saved (the PNG itself is matplotlib's); costs are counted:
artists in the figure, points evaluated, Python calls.
"""

import numpy as np
import pytest

import ecam
import ecam.plot as plot
from conftest import CAMS
from ecam.laws import LawTable
from ecam.profile import CamProfile, Segment
from test_profile import many_segments, python_calls

matplotlib = pytest.importorskip("matplotlib")
from matplotlib.collections import LineCollection  # noqa: E402


@pytest.fixture
def drawn(monkeypatch, tmp_path):
    """plot_profile(profile, **options) -> the figure it would have saved."""
    import matplotlib.pyplot as plt

    figures = []
    monkeypatch.setattr(plot, "save_figure", lambda fig, path: figures.append(fig))

    def draw(profile, **options):
        plot.plot_profile(profile, tmp_path / "cam.png", **options)
        return figures[-1]

    yield draw
    for fig in figures:
        plt.close(fig)


def curve(ax):
    """The plotted derivative: one LineCollection whose paths are the segments, drawn first."""
    return ax.collections[0]


def bars(ax, color):
    rgba = matplotlib.colors.to_rgba(color)
    return [c for c in ax.collections if isinstance(c, LineCollection)
            and np.allclose(c.get_colors()[0], rgba) and c.get_linewidth()[0] == 2.5]


def test_each_segment_is_drawn_on_its_own_points_with_its_own_values(drawn):
    profile = ecam.load_cam(CAMS / "combination_drrd.toml")
    fig = drawn(profile)
    for order, ax in enumerate(fig.axes):
        paths = curve(ax).get_segments()
        assert len(paths) == len(profile.segments)
        for seg, points in zip(profile.segments, paths):
            x, y = points[:, 0], points[:, 1]
            assert x[0] == seg.master_start and x[-1] == seg.master_end and np.all(np.diff(x) > 0)
            assert np.array_equal(y, seg.evaluate(x, order, "right"))
            assert x.size >= plot.PER_SEGMENT + 2
    joints = [c for c in fig.axes[0].collections if c.get_linestyle()[0][1] is not None]  # dashed
    assert [s[0, 0] for s in joints[0].get_segments()] == profile.joints().tolist()
    assert [t.get_text() for t in fig.axes[0].texts] == [seg.label for seg in profile.segments]


def test_a_jump_is_a_bar_from_one_side_to_the_other_and_no_line_bridges_it(drawn):
    """A dwell into a constant velocity: the velocity steps at the joints (errors, red)."""
    cam = CamProfile.from_segments([Segment.from_span(90.0), Segment.from_span(90.0, 10.0, "constant_velocity"),
                                    Segment.from_span(90.0), Segment.from_span(90.0, -10.0, "constant_velocity")])
    report = cam.check()
    fig = drawn(cam)
    velocity = fig.axes[1]
    jumps = [d for d in report.errors if d.order == 1]
    (red,) = bars(velocity, "C3")
    drawn_bars = [(s[0, 0], s[0, 1], s[1, 0], s[1, 1]) for s in red.get_segments()]
    assert len(jumps) == 4 and sorted(drawn_bars) == sorted((d.master, d.left, d.master, d.right) for d in jumps)
    for points in curve(velocity).get_segments():  # each path flat: no line from one level to the other
        assert np.ptp(points[:, 1]) == 0.0
    assert "4 discontinuities (red)" in fig.axes[0].get_title()


def test_a_dense_cam_is_drawn_as_bands_and_the_title_says_what_is_left_out(drawn, monkeypatch):
    """Past MARKED segments: each curve is its band per slice of the period, the joints and jumps
    are not drawn but counted in the title, and no segment is named; with 5 samples only, the
    points inside each segment still show the cycloidal velocity's peak, 2 stroke / span."""
    monkeypatch.setattr(plot, "MARKED", 16)
    profile = many_segments(64)
    fig = drawn(profile, samples=5)
    title = fig.axes[0].get_title()
    assert "too dense to mark: 63 joints, 64 jerk jumps" in title
    assert "segment names left out (over 60 segments)" in title and "dashed: joints" not in title
    for ax in fig.axes:
        assert not ax.collections and not ax.texts and len(ax.lines) == 1
    x, y = fig.axes[1].lines[0].get_data()
    assert x.size <= 2 * plot.BANDS  # at most one stroke up and down per slice
    assert 0.99 * 2.0 < y.max() <= 2.0  # cycloidal rise of 1 over 1: peak velocity 2
    position = fig.axes[0].lines[0].get_ydata()
    assert position.min() == 0.0 and position.max() == 1.0


def artists(fig):
    return [len(ax.lines) + len(ax.collections) + len(ax.texts) for ax in fig.axes]


@pytest.mark.parametrize("marked", [1000, 16])
def test_the_figure_holds_the_same_artists_for_any_number_of_segments(drawn, monkeypatch, marked):
    """Past LABELLED segments (64 and 256, with the joints drawn and, with MARKED 16, as bands):
    as many matplotlib objects for four times the segments."""
    monkeypatch.setattr(plot, "MARKED", marked)
    assert artists(drawn(many_segments(64))) == artists(drawn(many_segments(256)))


def test_the_cost_is_the_points_plus_the_segments(drawn, monkeypatch):
    """Every evaluated point once (the samples, the joints and PER_SEGMENT points inside each
    segment, four derivatives), besides check(); and a few hundred Python calls per segment
    (matplotlib's path per segment: 880 measured), where one artist per segment and derivative took
    8300."""
    evaluated = []
    original = LawTable.pieces_at

    def counting(self, piece, t, order):
        evaluated.append(np.size(t))
        return original(self, piece, t, order)

    profile = many_segments(256)
    drawn(many_segments(8))  # matplotlib's first-use work
    monkeypatch.setattr(LawTable, "pieces_at", counting)
    drawn(profile, samples=1001)
    breaks = len(profile.breaks())
    points = 1001 + 255 + 256 * plot.PER_SEGMENT
    assert sum(evaluated) <= 4 * (points + 256) + 8 * breaks, (sum(evaluated), points)
    monkeypatch.setattr(LawTable, "pieces_at", original)
    small = python_calls(lambda: drawn(many_segments(64)))
    large = python_calls(lambda: drawn(many_segments(256)))
    assert (large - small) / 192 < 1500, (small, large)
