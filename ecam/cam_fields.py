"""Every field of a cam file (TOML), as :func:`ecam.camfile.parse_cam` reads it: the table the
reference page is generated from (see :mod:`ecam.field_table`; ``tests/test_field_tables.py``
holds it to the parser)."""

from __future__ import annotations

from .field_table import REQUIRED, Field
from .laws import LAW_NAMES
from .spline import MAX_SPLINE_PIECES
from .profile import MAX_PERIOD, MAX_SEGMENTS, MAX_SLAVE, MIN_PERIOD
from .table import INTERPOLATIONS, MAX_MASTER_COUNTS
from .tappet import DIRECTIONS, MAX_COMPENSATION_S
from .table_spec import (DEFAULT_COUNTS_PER_UNIT, DEFAULT_INTERP, DEFAULT_MASTER_COUNTS, MAX_COUNTS_PER_UNIT,
                         MAX_POINTS, MIN_COUNTS_PER_UNIT)
from .validate import MAX_MAGNITUDE

__all__ = ["CAM_FIELDS", "CAM_TABLES"]

_PARSER = "ecam.camfile"
_SPEC = "ecam.table_spec (TableSpec)"
_FILE_LAWS = (*LAW_NAMES, "poly5", "poly7", "spline")
_TAPPET = "ecam.tappet (TappetTrack)"

#: The tables of a cam file and what each holds, in the reference's order.
CAM_TABLES = {
    "": "The cam: its units, its master period and where the slave starts.",
    "table": "Defaults for `ecam compile` and `ecam export` (the command line's options win). "
             "Every field is optional; a cam without `[table]` compiles with the defaults below, "
             "and `ecam compile` says which it applied.",
    "segment": "One `[[segment]]` per piece of the motion, in master order; the segments cover the "
               "master period without gaps.",
    "tappet": "One `[[tappet]]` per digital cam switch (PLCopen MC_DigitalCamSwitch; ecam.tappet): an "
              "output on from `on` to `off` on the master position. Optional; exports carry them.",
}

_BOUNDARY = []
for _end in ("start", "end"):
    for _order, (_what, _unit) in enumerate((("velocity", "slave units / master unit"),
                                             ("acceleration", "slave units / master unit^2"),
                                             ("jerk", "slave units / master unit^3")), start=1):
        _BOUNDARY.append(Field(
            "segment", f"{_end}_{_what}", "number or \"match\"",
            f"poly5/poly7 only: the {_what} at the segment's {_end}; \"match\" takes the neighbouring "
            "segment's (VDI 2143 motion-to-motion)" + (" (poly7 only)" if _what == "jerk" else ""),
            unit=_unit, default=0.0, source=_PARSER,
            limits=f"finite, magnitude <= {MAX_MAGNITUDE:g}, also once normalized (value x span^{_order} / stroke)",
            when=(("segment.law", "poly7"),), probe=False))

CAM_FIELDS: tuple[Field, ...] = (
    Field("", "name", "string", "The cam's name: tables, exports and reports carry it.",
          default_text="the file name without .toml", source=_PARSER),
    Field("", "master_unit", "string", "The master's unit, for reports and plots (free text).",
          default="deg", source=_PARSER),
    Field("", "slave_unit", "string", "The slave's unit, for reports, plots and tolerances such as "
          "\"0.01 mm\" (free text).", default="mm", source=_PARSER),
    Field("", "master_period", "number", "Master units per cycle of the cam.", unit="master units",
          default=REQUIRED, minimum=MIN_PERIOD, maximum=MAX_PERIOD, source="ecam.profile"),
    Field("", "periodic", "boolean", "The cam repeats: master positions wrap, and the seam is "
          "checked like a joint.", default=True, source=_PARSER),
    Field("", "start", "number", "The slave position at master 0.", unit="slave units", default=0.0,
          minimum=-MAX_SLAVE, maximum=MAX_SLAVE, source=_PARSER),
    Field("", "net_stroke", "number", "Slave units the slave advances per master period (a rotary "
          "knife, an indexing turret, a feed roll); it must equal the segments' total stroke.",
          unit="slave units", default_text="none (the slave returns to its start each period)",
          minimum=-2 * MAX_SLAVE, maximum=2 * MAX_SLAVE, limits="periodic cams only", probe=False,
          source="ecam.profile"),
    Field("", "table", "table", "The `[table]` settings below.", default_text="the defaults below"),
    Field("", "segment", "array of tables", "The `[[segment]]` entries below.", default=REQUIRED,
          limits=f"1 .. {MAX_SEGMENTS} segments"),
    Field("", "tappet", "array of tables", "The `[[tappet]]` entries below.", default_text="none",
          limits=f"0 .. {MAX_SEGMENTS} tappets"),

    Field("table", "interp", "choice", "The interpolation kind: positions only (linear), position "
          "and slope (cubic Hermite, C1), position, slope and curvature (quintic Hermite, C2), or the "
          "kind and point count that meet the tolerance with the fewest bytes (auto).",
          default=DEFAULT_INTERP, choices=INTERPOLATIONS, source=_SPEC),
    Field("table", "points", "integer", "Stored points (intervals + 1).",
          default_text="none: give points or tolerance (here, or --points / --tolerance)",
          minimum=2, maximum=MAX_POINTS, limits="points - 1 divides master_counts; at most one of "
          "points and tolerance", source=_SPEC),
    Field("table", "tolerance", "number or string", "The largest error the table may have: slave "
          "units, or a string such as \"2 counts\" or \"0.01 mm\".", unit="slave units or counts",
          default_text="none", limits=f"> 0 and <= {MAX_MAGNITUDE:g}; at least the 1/2-count final "
          "rounding", source=_SPEC),
    Field("table", "interpolation_tolerance", "number or string", "With `tolerance`: the largest "
          "error the table may add to the 1/2 count that rounding every lookup to whole counts costs "
          "(interpolation, stored data, arithmetic), in the same forms, e.g. \"0.05 counts\". The "
          "certified bound then meets both: at most `tolerance`, and at most 1/2 count + this. For a "
          "tolerance of a count or so, where that 1/2 count is most of it: a 1-count tolerance alone "
          "lets the table add up to 1/2 count more (measured 0.73 counts on a 26-bit drum); with "
          "\"0.05 counts\" here the measured error stays within 0.55 (docs/table_formats.md).",
          unit="slave units or counts", default_text="none: the tolerance alone sizes the table",
          limits=f"> 0 and <= {MAX_MAGNITUDE:g}; only with a tolerance", source=_SPEC),
    Field("table", "master_counts", "integer", "The master period in encoder counts.",
          unit="counts", default=DEFAULT_MASTER_COUNTS, minimum=2, maximum=MAX_MASTER_COUNTS,
          source=_SPEC),
    Field("table", "slave_counts_per_unit", "number", "Slave counts per slave unit.",
          unit="counts / slave unit", default=DEFAULT_COUNTS_PER_UNIT, minimum=MIN_COUNTS_PER_UNIT,
          maximum=MAX_COUNTS_PER_UNIT, limits="every table position inside int32", source=_SPEC),

    Field("table", "horner_bits", "integer", "The word width of the expanded form's Horner values "
          "(firmware_tables/FORMAT.md, \"Expanded form\"): 64, the finest fixed-point format int64 "
          "allows; 32, the finest whose `ecam_poly_init` expansion keeps every Horner value in 32-bit "
          "words, so that 32-bit cores (Cortex-M4) run its narrow kernels, one 32x32 multiply per "
          "degree, at fewer work bits (the certificate prices them; the cost grows with the stroke "
          "in counts). The blob's format is the same either way.", unit="bits", default=64,
          minimum=32, maximum=64, limits="32 or 64 only", source=_SPEC),

    Field("segment", "name", "string", "A name for reports and plots.", default="", source=_PARSER),
    Field("segment", "law", "choice", "The motion law (`ecam laws`), a dwell, a polynomial solved "
          "from boundary conditions (poly5, poly7), or a spline (knots and derivatives, as `ecam fit` "
          "writes it).", default_text="give exactly one of law and "
          "combination", choices=_FILE_LAWS, source=_PARSER),
    Field("segment", "combination", "array", "Two half laws joined with matched velocity "
          "(ecam.design), e.g. [\"half_cycloid_start\", \"half_harmonic_end\"].",
          default_text="give exactly one of law and combination", limits="two law names",
          source=_PARSER),
    Field("segment", "accel_ratio", "number", "Combination only: peak |acceleration| of the first "
          "law over that of the second.", default=REQUIRED, minimum=1e-6, maximum=1e6,
          when=(("segment.law", None), ("segment.combination", ["half_cycloid_start", "half_harmonic_end"])),
          source="ecam.design"),
    Field("segment", "span", "number", "The segment's length in master units.", unit="master units",
          default_text="give exactly one of span and end", minimum=0.0, exclusive_minimum=True,
          limits="at least 1e-9 of master_period", source="ecam.profile", probe=False),
    Field("segment", "end", "number", "The master position where the segment ends (absolute).",
          unit="master units", default_text="give exactly one of span and end", source=_PARSER,
          probe=False),
    Field("segment", "start", "number", "The master position where the segment starts; must equal "
          "the previous segment's end (anything else is a gap or an overlap).", unit="master units",
          default_text="the previous segment's end", source=_PARSER, probe=False),
    Field("segment", "stroke", "number", "The slave's travel over the segment.", unit="slave units",
          default_text="0 for a dwell; else give stroke or to", source=_PARSER, probe=False),
    Field("segment", "to", "number", "The slave position at the segment's end (absolute).",
          unit="slave units", default_text="the start plus the stroke", minimum=-MAX_SLAVE,
          maximum=MAX_SLAVE, source=_PARSER, probe=False),
    Field("segment", "from", "number", "An explicit slave start: a deliberate position jump, which "
          "`ecam check` reports.", unit="slave units", default_text="the previous segment's end",
          minimum=-MAX_SLAVE, maximum=MAX_SLAVE, source=_PARSER, probe=False),
    *_BOUNDARY,
    Field("segment", "knots", "array", "spline only: the knots' master positions from the segment's "
          "start, 0 first, increasing; the last is the segment's span.", unit="master units",
          default=REQUIRED, limits=f"2 .. {MAX_SPLINE_PIECES + 1} knots, strictly increasing; no span, end, "
          "stroke or to beside them", when=(("segment.law", "spline"),), source="ecam.spline", probe=False),
    Field("segment", "derivatives", "array", "spline only: one row per knot interval, [position, "
          "velocity, acceleration, jerk, snap, crackle] at its first knot (from the right); the "
          "position is from the segment's start (0 in the first row). The interval follows the "
          "row's Taylor polynomial of degree 5.", unit="slave units / master unit^k",
          default=REQUIRED, limits="as many rows as knot intervals, 6 finite numbers each",
          when=(("segment.law", "spline"),), source="ecam.spline", probe=False),

    Field("tappet", "name", "string", "A name for reports and exports.", default="", source=_TAPPET),
    Field("tappet", "on", "number", "The first master position where the output is on "
          "(PLCopen FirstOnPosition).", unit="master units", default=REQUIRED,
          limits="within 0 .. master_period", source=_TAPPET, probe=False),
    Field("tappet", "off", "number", "The last master position where the output is on "
          "(LastOnPosition); below `on`, the window wraps through the period end.",
          unit="master units", default=REQUIRED, limits="within 0 .. master_period", source=_TAPPET,
          probe=False),
    Field("tappet", "direction", "choice", "The master's direction of motion in which the output "
          "switches (PLCopen AxisDirection 0, 1, 2).", default="both", choices=DIRECTIONS,
          source=_TAPPET),
    Field("tappet", "hysteresis", "number", "How far the master must move away from the last "
          "switching point before the output switches again (PLCopen track Hysteresis).",
          unit="master units", default=0.0, minimum=0.0, limits="below half the master period",
          source=_TAPPET),
    Field("tappet", "on_compensation", "number", "Compensation time of the rising edge (PLCopen "
          "OnCompensation): negative brings it forward, e.g. -0.02 for a valve's 20 ms dead time.",
          unit="s", default=0.0, minimum=-MAX_COMPENSATION_S, maximum=MAX_COMPENSATION_S, source=_TAPPET),
    Field("tappet", "off_compensation", "number", "Compensation time of the falling edge "
          "(OffCompensation).", unit="s", default=0.0, minimum=-MAX_COMPENSATION_S,
          maximum=MAX_COMPENSATION_S, source=_TAPPET),
)
