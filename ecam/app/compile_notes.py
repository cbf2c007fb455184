"""What `ecam compile` adds below a table's certificate for a newcomer: the table settings it took
from ecam's defaults (a cam file without them compiles, but for a machine nobody chose), and the
master counts that would put the joints listed off the table points on points."""

from __future__ import annotations

from ecam.certificate import FINAL_ROUNDING_COUNTS
from ecam.joint_grid import joint_grid
from ecam.table_spec import DEFAULT_COUNTS_PER_UNIT, DEFAULT_INTERP, DEFAULT_MASTER_COUNTS

# The settings a table takes from ecam when neither the cam's [table] nor the command line gives
# them, with the command-line option that sets each.
_DEFAULTS = (("interp", "--interp", DEFAULT_INTERP), ("master_counts", "--master-counts", DEFAULT_MASTER_COUNTS),
             ("slave_counts_per_unit", "--slave-counts-per-unit", DEFAULT_COUNTS_PER_UNIT))


CHECKED_SEGMENTS = 1000
# A table sized by a tolerance of at most this many counts (the final rounding's 1/2 count is half
# of it or more), whose share above the rounding exceeds ROUNDING_SHARE counts, gets a note on
# interpolation_tolerance (docs/table_formats.md, "The final rounding and what the table adds").
ROUNDING_TOLERANCE = 1.0
ROUNDING_SHARE = 0.05


def defaults_applied(profile, args) -> dict:
    """``{setting: value}`` for each table setting ecam's default supplied."""
    return {name: value for name, option, value in _DEFAULTS
            if getattr(args, name, None) is None and name not in profile.table}


def defaults_text(applied: dict) -> str | None:
    """One line naming the defaults applied, or None."""
    if not applied:
        return None
    listed = ", ".join(f"{name} = {value:g}" if isinstance(value, float) else f"{name} = {value}"
                       for name, value in applied.items())
    return (f"  defaults applied (the cam's [table] does not set them): {listed}; set them for your "
            "machine in [table] or with " + ", ".join(option for name, option, _ in _DEFAULTS if name in applied))


def joint_hint(profile, table) -> str | None:
    """One line saying which master counts put the joints off the table points on points."""
    report = table.report
    off = report.get("joints_off_points") or []
    if not off:
        return None
    # Every joint, so that the hint keeps the ones on points there; a long cam's check takes
    # seconds, so past CHECKED_SEGMENTS its segment starts stand for its joints.
    if len(profile.segments) <= CHECKED_SEGMENTS:
        found = (jump.master for jump in profile.check().discontinuities)
    else:
        found = (segment.master_start for segment in profile.segments)
    joints = sorted({*off, *found})
    grid = joint_grid(profile.master_period, joints, report["master_counts"])
    if grid is None:
        return ("  no master_counts up to 2^31 puts every joint on a whole count: their cost stays "
                "in the bound")
    if grid.master_counts == report["master_counts"]:
        return (f"  at master_counts {grid.master_counts} a table of {grid.smallest_points} points (or "
                f"k x {grid.smallest_points - 1} + 1) puts every joint on a point")
    return (f"  --master-counts {grid.master_counts} (any multiple of {grid.multiple}) puts every joint on a "
            f"whole count; then a table of {grid.smallest_points} points (or k x {grid.smallest_points - 1} "
            "+ 1) has them on points")


def rounding_hint(table) -> str | None:
    """One line, for a table sized by a tolerance of a count or less without an interpolation
    tolerance, saying what the table adds to the final rounding and how to hold it lower."""
    report = table.report
    tolerance = report.get("tolerance_counts")
    # (a tolerance in slave units is converted to counts in floating point: 1 count given as
    # 1 / counts-per-unit may come back a rounding above 1)
    if tolerance is None or tolerance > ROUNDING_TOLERANCE * (1.0 + 1e-9) or "interpolation_tolerance_counts" in report:
        return None
    share = report["predicted_error_counts"] - FINAL_ROUNDING_COUNTS
    if share <= ROUNDING_SHARE:
        return None
    return (f"  the final rounding to whole counts costs {FINAL_ROUNDING_COUNTS:g} count of every lookup and this "
            f"table adds up to {share:.3g} more; --interpolation-tolerance (interpolation_tolerance in [table]), "
            f"e.g. '{ROUNDING_SHARE:g} counts', holds that part lower with more points")
