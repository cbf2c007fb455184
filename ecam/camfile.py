"""Cam files (TOML) -> CamProfile.

The reader checks the file's shape here (field names, TOML types, which fields go together) with
:mod:`ecam.validate`; every rule of the cam itself is checked once, by the Python API it hands the
values to (:class:`~ecam.profile.Segment`, :class:`~ecam.profile.CamProfile`,
:func:`~ecam.design.combination_segments`), whose messages it renames to the file's fields
(``master_start`` -> ``start``, ``slave_end`` -> ``to``, ...). :meth:`CamProfile.to_toml` writes
the format back.
"""

from __future__ import annotations

import os
import stat
import tomllib
from pathlib import Path

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .design import combination_segments
from .errors import CamFileError
from .laws import LAW_NAMES, LAWS
from .profile import (BOUNDARY_KEYS, TABLE_KEYS, CamProfile, Segment, check_master_period, check_segment_count,
                      check_span, check_tiling)
from .spline import spline_law
from .table import INTERPOLATIONS, MAX_MASTER_COUNTS
from .tappet import DIRECTIONS, TAPPET_KEYS, TappetTrack
from .table_spec import HORNER_BITS, MAX_COUNTS_PER_UNIT, MAX_POINTS, MIN_COUNTS_PER_UNIT, parse_tolerance
from .validate import Fields, show, show_path

__all__ = ["CAMS_DIR", "load_cam", "parse_cam", "read_bounded", "read_tappets", "read_toml", "show"]

# The built-in cams (the seeds'), shipped with the package: a link to firmware_tables/cams in a
# checkout, a copy in an installed wheel.
CAMS_DIR = Path(__file__).resolve().parent / "cams"

_TOP_KEYS = {"name", "master_unit", "slave_unit", "master_period", "periodic", "start", "net_stroke", "table",
             "segment", "tappet"}
_BOUNDARY_FIELDS = tuple(f"{end}_{what}" for end in ("start", "end") for what in BOUNDARY_KEYS)
_SPLINE_FIELDS = ("knots", "derivatives")  # a spline segment's (ecam.spline), and only its
_SEGMENT_KEYS = {"name", "law", "combination", "accel_ratio", "span", "end", "start", "stroke", "to", "from",
                 *_BOUNDARY_FIELDS, *_SPLINE_FIELDS}
_POLYNOMIALS = {"poly5": 5, "poly7": 7}
# Every name a file's `law` may hold: the laws, the dwell, and the polynomials solved here.
FILE_LAW_NAMES = (*LAW_NAMES, *_POLYNOMIALS, "spline")
# The Python API's names for what a cam file calls start, end, from and to.
_FILE_NAMES = {"master_start": "start", "master_end": "end", "slave_start": "from", "slave_end": "to",
               "segments": "segment"}


def load_cam(path) -> CamProfile:
    """Read a cam file (TOML) into a :class:`~ecam.profile.CamProfile`.

    Raises
    ------
    CamFileError
        One line naming the field, the value and what was expected.
    """
    path = Path(path)
    return parse_cam(read_toml(path, "cam file"), source=str(path))


# Cam and scene files are a few kilobytes; this bound keeps a wrong path (a log, an image, a
# device) from being read whole.
MAX_FILE_BYTES = 4 * 2**20


def read_bounded(path, what: str, limit: int | None = None) -> bytes:
    """The bytes of a file, read without waiting and without bound on nothing.

    Only regular files of at most ``limit`` bytes (default :data:`MAX_FILE_BYTES`) are read, so
    a device such as ``/dev/zero`` or a FIFO is refused at once instead of read without bound or waited on, and
    a kernel file that looks regular but has nothing to read now (``/proc/kmsg``) is refused
    instead of waited on. Everything that keys, hashes or parses a user's file reads it here.

    Raises
    ------
    CamFileError
        A missing, unreadable, irregular or oversized file: one line naming the file and what
        is wrong.
    """
    limit = MAX_FILE_BYTES if limit is None else limit
    path = Path(path)
    shown = show_path(path)  # cut to 60 characters: a hostile path cannot flood the terminal
    try:
        # O_NONBLOCK: opening a FIFO with no writer must not wait; the type check follows.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise CamFileError(f"{what} {shown} does not exist") from None
    except OSError as exc:
        raise CamFileError(f"{what} {shown} cannot be read: {exc.strerror or exc}") from None
    except ValueError:  # a NUL character, which no path holds
        raise CamFileError(f"{what} {shown} should be a path without NUL characters") from None
    try:
        # The type before anything else: a directory opens read-only but cannot be read.
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise CamFileError(f"{what} {shown} should be a regular file")
        if info.st_size > limit:
            raise CamFileError(f"{what} {shown}: {info.st_size} bytes should be at most "
                               f"{limit}")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, limit + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except BlockingIOError:  # still non-blocking: a kernel file with nothing to read now
        raise CamFileError(f"{what} {shown} cannot be read without waiting (a kernel or device "
                           "file?)") from None
    except OSError as exc:
        raise CamFileError(f"{what} {shown} cannot be read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if size > limit:  # the file grew while we read it (or /proc reports no size)
        raise CamFileError(f"{what} {shown}: more than {limit} bytes")
    return b"".join(chunks)


def read_toml(path, what: str) -> dict:
    """Parse a TOML file into a mapping (read by :func:`read_bounded`).

    Raises
    ------
    CamFileError
        A missing, unreadable, irregular, oversized or malformed file (nesting too deep for
        the parser included): one line naming the file and what is wrong.
    """
    data = read_bounded(path, what)
    shown = show_path(path)
    try:
        return tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise CamFileError(f"{what} {shown} should be UTF-8 text: {exc.reason} at byte {exc.start}") from None
    except tomllib.TOMLDecodeError as exc:
        raise CamFileError(f"{what} {shown} is not valid TOML: {exc}") from None
    except ValueError as exc:  # an integer longer than Python converts (4300 digits)
        raise CamFileError(f"{what} {shown} cannot be read as TOML: {str(exc).split(';')[0]}") from None
    except RecursionError:
        raise CamFileError(f"{what} {shown}: arrays or tables nest too deeply to parse") from None


def parse_cam(data: dict, source: str = "<cam>") -> CamProfile:
    """Build a profile from the parsed TOML mapping (see the README for the format).

    Parameters
    ----------
    data : mapping
        The parsed file.
    source : str
        The file, for messages (``cam <source>: <field>: ...``) and the default cam name.

    Raises
    ------
    CamFileError
        One line naming the field, the value and what was expected.
    """
    top = Fields(data, "", f"cam {source}", _TOP_KEYS)
    if "master_period" not in top:
        raise top.error("master_period: missing; expected a number")
    with top.calling():
        period = check_master_period(top.get("master_period"))
    periodic = top.boolean("periodic", default=True)
    slave_unit = top.text("slave_unit", default="mm", maximum=validate.MAX_UNIT_CHARS)
    table = _table(top, slave_unit)
    raw_segments = top.get("segment")
    if raw_segments is None:
        raise top.error("segment: missing; expected at least one [[segment]] table")
    if not isinstance(raw_segments, list) or not all(isinstance(s, dict) for s in raw_segments):
        raise top.error(f"segment: {show(raw_segments)} should be an array of tables ([[segment]])")
    with top.calling():
        check_segment_count(len(raw_segments), "segment")  # before any is built

    # Segments in order; a poly5/poly7 waits (as its Fields and placement) for its neighbours.
    entries: list = []
    master, slave = 0.0, top.number("start", default=0.0)
    for i, raw in enumerate(raw_segments):
        r = Fields(raw, f"segment[{i}]", top.source, _SEGMENT_KEYS)
        if ("law" in r) == ("combination" in r):
            raise r.error(f"{r.where}: give exactly one of 'law' or 'combination'")
        law_name = r.choice("law", FILE_LAW_NAMES) if "law" in r else None
        for key in _BOUNDARY_FIELDS:
            if key in r and law_name not in _POLYNOMIALS:
                raise r.error(f"{r.name(key)}: {show(r.get(key))} should be absent: only poly5/poly7 "
                              "segments take boundary conditions")
        if "accel_ratio" in r and law_name is not None:
            raise r.error(f"{r.name('accel_ratio')}: {show(r.get('accel_ratio'))} should be absent: only a "
                          "combination takes one")
        for key in _SPLINE_FIELDS:
            if key in r and law_name != "spline":
                raise r.error(f"{r.name(key)}: should be absent: only spline segments take knots and derivatives")
        if law_name == "spline":
            segment = _spline(r, master, slave)
            entries.append(segment)
            master, slave = segment.master_end, segment.slave_end
            continue
        placement, master, slave = _place(r, master, slave, period, dwell=law_name == "dwell")
        if law_name is None:
            entries.extend(_combination(r, placement))
        elif law_name in _POLYNOMIALS:
            entries.append((r, law_name, placement))
        else:
            with r.calling(_file_name_in(r)):
                entries.append(Segment(*placement, law_name, r.text("name", default="")))
    with top.calling(_file_name):  # placement first: a 'match' reads a neighbour's derivatives
        check_tiling([entry[2][:2] if isinstance(entry, tuple) else (entry.master_start, entry.master_end)
                      for entry in entries], period)
    segments = [_polynomial(entries, k, periodic) if isinstance(entry, tuple) else entry
                for k, entry in enumerate(entries)]
    net_stroke = top.number("net_stroke")  # checked against the strokes by CamProfile
    tappets = read_tappets(top)
    with top.calling(_file_name):
        return CamProfile(segments, period, periodic, name=top.get("name", Path(source).stem),
                          master_unit=top.get("master_unit", "deg"), slave_unit=slave_unit, table=table,
                          net_stroke=net_stroke, tappets=tappets)


def _file_name(field: str) -> str:
    """A field of the Python API as the cam file calls it (``segment[2].master_start`` ->
    ``segment[2].start``)."""
    where, _, key = field.rpartition(".")
    key = _FILE_NAMES.get(key, key)
    return f"{where}.{key}" if where else key


def _file_name_in(r: Fields):
    """Renames a field of one segment; its slave start is the file's top-level ``start`` unless
    the segment says ``from``."""
    def rename(field: str) -> str:
        if field == "slave_start" and "from" not in r:
            return "start"
        return _file_name(r.name(field))
    return rename


def _place(r: Fields, master: float, slave: float, period: float, dwell: bool):
    """Where the segment of ``r`` runs: (master_start, master_end, slave_start, slave_end), and the
    master and slave positions the next segment starts from. A written ``start`` or ``from`` is
    taken as written (a gap, an overlap or a jump is for the profile to report), and so are
    ``end`` and ``to``; ``span`` and ``stroke`` are added to the start."""
    if ("span" in r) == ("end" in r):
        raise r.error(f"{r.where}: give exactly one of 'span' or 'end' (master units)")
    if "stroke" in r and "to" in r:
        raise r.error(f"{r.where}: give at most one of 'stroke' or 'to'")
    master_start = r.number("start", default=master)
    slave_start = r.number("from", default=slave)
    if "span" in r:
        with r.calling(_file_name_in(r)):  # as written: a span lost in rounding is too small
            span = check_span(r.number("span"), period, "span")
        master_end = master_start + span
    else:
        master_end = r.number("end")
    if "to" in r:
        slave_end = r.number("to")
    elif "stroke" in r:
        slave_end = slave_start + r.number("stroke")
    elif dwell:
        slave_end = slave_start
    else:
        raise r.error(f"{r.name('stroke')}: missing; expected a number (slave units) or 'to'")
    return (master_start, master_end, slave_start, slave_end), master_end, slave_end


def _spline(r: Fields, master: float, slave: float) -> Segment:
    """A ``law = "spline"`` segment: its knots give its span, its rows where it ends."""
    for key in ("span", "end", "stroke", "to"):
        if key in r:
            raise r.error(f"{r.name(key)}: {show(r.get(key))} should be absent: a spline's knots give its span "
                          "and its derivatives where it ends")
    for key in _SPLINE_FIELDS:
        if key not in r:
            raise r.error(f"{r.name(key)}: missing; expected " + (
                "a list of master positions from the segment's start" if key == "knots"
                else "a list of rows [position, velocity, acceleration, jerk, snap, crackle], one per knot interval"))
    master_start = r.number("start", default=master)
    slave_start = r.number("from", default=slave)
    with r.calling():
        law = spline_law(r.get("knots"), r.get("derivatives"))
    with r.calling(_file_name_in(r)):
        return Segment(master_start, master_start + law.span, slave_start, slave_start + law.end_position, law,
                       r.text("name", default=""))


def _combination(r: Fields, placement) -> tuple[Segment, Segment]:
    """The two solved segments of a ``combination = [first, second]`` segment."""
    laws = r.get("combination")
    if not (isinstance(laws, list) and len(laws) == 2 and all(isinstance(x, str) for x in laws)):
        raise r.error(f"{r.name('combination')}: {show(laws)} should be a list of two law names")
    with r.calling():
        for k, name in enumerate(laws):
            validate.choice(f"combination[{k}]", name, sorted(LAWS))
    if "accel_ratio" not in r:
        raise r.error(f"{r.name('accel_ratio')}: missing; expected a number (peak |acceleration| of the "
                      "first law over that of the second)")
    ratio = r.get("accel_ratio")  # checked by combination_segments
    master_start, master_end, slave_start, slave_end = placement
    with r.calling(_file_name_in(r)):
        return combination_segments(laws[0], laws[1], master_start=master_start, span=master_end - master_start,
                                    slave_start=slave_start, stroke=slave_end - slave_start, accel_ratio=ratio,
                                    name=r.text("name", default=""))


def _polynomial(entries: list, k: int, periodic: bool) -> Segment:
    """Solve the poly5/poly7 entry ``k`` from its boundary conditions (user units), where the
    string 'match' takes the value of the neighbouring segment (VDI 2143 motion-to-motion)."""
    r, law_name, placement = entries[k]
    degree = _POLYNOMIALS[law_name]
    conditions = {}
    for end in ("start", "end"):
        for order, what in enumerate(BOUNDARY_KEYS[: 2 if degree == 5 else 3], start=1):
            key = f"{end}_{what}"
            if r.get(key) == "match":
                index = k - 1 if end == "start" else k + 1
                if periodic:
                    index %= len(entries)
                if not 0 <= index < len(entries) or isinstance(entries[index], tuple):
                    raise r.error(f"{r.name(key)}: 'match' should have a neighbouring segment with a fixed law")
                conditions[key] = entries[index].at(1.0 if end == "start" else 0.0, order)
            elif key in r:
                conditions[key] = r.number(key)
        if degree == 5 and f"{end}_jerk" in r:
            conditions[f"{end}_jerk"] = r.get(f"{end}_jerk")  # refused by Segment.polynomial
    with r.calling(_file_name_in(r)):
        return Segment.polynomial(*placement, degree=degree, name=r.text("name", default=""), **conditions)


def read_tappets(top: Fields) -> tuple:
    """The ``[[tappet]]`` tables: digital cam switches (:mod:`ecam.tappet`); their range against
    the master period is checked by CamProfile (a scene's, by the rig against its cam)."""
    raw = top.get("tappet")
    if raw is None:
        return ()
    if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
        raise top.error(f"tappet: {show(raw)} should be an array of tables ([[tappet]])")
    with top.calling():
        check_segment_count(len(raw), "tappet")
    out = []
    for i, item in enumerate(raw):
        r = Fields(item, f"tappet[{i}]", top.source, set(TAPPET_KEYS))
        for key in ("on", "off"):
            if key not in r:
                raise r.error(f"{r.name(key)}: missing; expected a number (master units)")
        values = {key: r.number(key) for key in ("on", "off", "hysteresis", "on_compensation",
                                                  "off_compensation") if key in r}
        if "direction" in r:
            values["direction"] = r.choice("direction", DIRECTIONS)
        with r.calling():
            out.append(TappetTrack(**values, name=r.text("name", default="")))
    return tuple(out)


def _table(top: Fields, slave_unit: str) -> dict:
    """The ``[table]`` settings, checked in type and range (TableSpec checks them again, with
    the command line's settings over them, when a table is compiled)."""
    t = top.table("table", allowed=TABLE_KEYS)
    out = {}
    if "interp" in t:
        out["interp"] = t.choice("interp", INTERPOLATIONS)
    if "points" in t:
        out["points"] = t.integer("points", minimum=2, maximum=MAX_POINTS)
    if "master_counts" in t:
        out["master_counts"] = t.integer("master_counts", minimum=2, maximum=MAX_MASTER_COUNTS)
    if "slave_counts_per_unit" in t:
        out["slave_counts_per_unit"] = t.number("slave_counts_per_unit", minimum=MIN_COUNTS_PER_UNIT,
                                                maximum=MAX_COUNTS_PER_UNIT)
    if "tolerance" in t:
        with t.calling(lambda field: field):
            parse_tolerance(t.get("tolerance"), t.name("tolerance"), slave_unit)
        out["tolerance"] = t.get("tolerance")
    if "interpolation_tolerance" in t:
        with t.calling(lambda field: field):
            parse_tolerance(t.get("interpolation_tolerance"), t.name("interpolation_tolerance"), slave_unit)
        if "tolerance" not in t:
            raise t.error(str(validate.fail(t.name("interpolation_tolerance"), t.get("interpolation_tolerance"),
                                            "given with a tolerance (it refines the tolerance's sizing)")))
        out["interpolation_tolerance"] = t.get("interpolation_tolerance")
    if "horner_bits" in t:
        out["horner_bits"] = t.integer("horner_bits", minimum=min(HORNER_BITS), maximum=max(HORNER_BITS))
        if out["horner_bits"] not in HORNER_BITS:
            raise t.error(str(validate.fail(t.name("horner_bits"), out["horner_bits"], "64 or 32")))
    return out
