"""Cam files (TOML) -> CamProfile. Every field is checked here, once, where it enters."""

from __future__ import annotations

import math
import os
import stat
import tomllib
from pathlib import Path

from .compile import parse_tolerance
from .design import combination_segments
from .errors import CamFileError, InputError
from .laws import law as _law, polynomial_from_boundary
from .profile import MAX_PERIOD, MIN_PERIOD, MIN_SPAN_FRACTION, CamProfile, Segment

__all__ = ["CAMS_DIR", "load_cam", "parse_cam", "read_toml"]

# The built-in cams (the seeds'), shipped with the package: a link to firmware_tables/cams in a
# checkout, a copy in an installed wheel.
CAMS_DIR = Path(__file__).resolve().parent / "cams"

_TOP_KEYS = {"name", "master_unit", "slave_unit", "master_period", "periodic", "start", "table", "segment"}
_TABLE_KEYS = {"interp", "points", "tolerance", "master_counts", "slave_counts_per_unit"}
_SEGMENT_KEYS = {
    "name", "law", "combination", "accel_ratio", "span", "end", "start", "stroke", "to", "from",
    "start_velocity", "end_velocity", "start_acceleration", "end_acceleration",
    "start_jerk", "end_jerk",
}
_BOUNDARY_KEYS = ("velocity", "acceleration", "jerk")
_POLYNOMIALS = {"poly5": 2, "poly7": 3}


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


def read_toml(path, what: str) -> dict:
    """Parse a TOML file into a mapping.

    Only regular files of at most :data:`MAX_FILE_BYTES` are read, so a device such as
    ``/dev/zero`` or a FIFO is refused at once instead of read without bound or waited on.

    Raises
    ------
    CamFileError
        A missing, unreadable, irregular, oversized or malformed file (nesting too deep for
        the parser included): one line naming the file and what is wrong.
    """
    path = Path(path)
    shown = repr(str(path))
    try:
        # O_NONBLOCK: opening a FIFO with no writer must not wait; the type check follows.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise CamFileError(f"{what} {shown} does not exist") from None
    except OSError as exc:
        raise CamFileError(f"{what} {shown} cannot be read: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as handle:
        info = os.fstat(handle.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise CamFileError(f"{what} {shown} should be a regular file")
        if info.st_size > MAX_FILE_BYTES:
            raise CamFileError(f"{what} {shown}: {info.st_size} bytes should be at most "
                               f"{MAX_FILE_BYTES}")
        try:
            data = handle.read(MAX_FILE_BYTES + 1)
        except OSError as exc:
            raise CamFileError(f"{what} {shown} cannot be read: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:  # the file grew while we read it
        raise CamFileError(f"{what} {shown}: more than {MAX_FILE_BYTES} bytes")
    try:
        return tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise CamFileError(f"{what} {shown} should be UTF-8 text: {exc.reason} at byte {exc.start}") from None
    except tomllib.TOMLDecodeError as exc:
        raise CamFileError(f"{what} {shown} is not valid TOML: {exc}") from None
    except RecursionError:
        raise CamFileError(f"{what} {shown}: arrays or tables nest too deeply to parse") from None


def parse_cam(data: dict, source: str = "<cam>") -> CamProfile:
    """Build a profile from the parsed TOML mapping (see the README for the format)."""
    _unknown(data, _TOP_KEYS, "")
    period = _number(data, "master_period", required=True, positive=True)
    if not MIN_PERIOD <= period <= MAX_PERIOD:
        raise CamFileError(f"master_period: {period!r} should be in {MIN_PERIOD:g}..{MAX_PERIOD:g}")
    periodic = _boolean(data, "periodic", default=True)
    slave = _number(data, "start", default=0.0)
    table = _table(data.get("table", {}))
    raw_segments = data.get("segment")
    if raw_segments is None:
        raise CamFileError("segment: missing; expected at least one [[segment]] table")
    if not isinstance(raw_segments, list) or not all(isinstance(s, dict) for s in raw_segments):
        raise CamFileError(f"segment: {show(raw_segments)} should be an array of tables ([[segment]])")
    if not raw_segments:
        raise CamFileError("segment: [] should hold at least one segment")

    segments: list[Segment] = []
    pending_polynomials = []
    master = 0.0
    for i, raw in enumerate(raw_segments):
        where = f"segment[{i}]"
        _unknown(raw, _SEGMENT_KEYS, where + ".")
        start = _number(raw, "start", where=where)
        if start is not None and not math.isclose(start, master, rel_tol=0, abs_tol=1e-9 * period):
            kind = "gap" if start > master else "overlap"
            raise CamFileError(
                f"{where}.start: {start!r} leaves a {kind}; the previous segment ends at {master!r}"
            )
        span = _number(raw, "span", where=where, positive=True)
        end = _number(raw, "end", where=where)
        if (span is None) == (end is None):
            raise CamFileError(f"{where}: give exactly one of 'span' or 'end' (master units)")
        if end is not None:
            span = end - master
            if not span > 0:
                raise CamFileError(f"{where}.end: {end!r} should be > the segment start {master!r}")
        if span < MIN_SPAN_FRACTION * period:
            raise CamFileError(f"{where}.span: {span!r} should be >= {MIN_SPAN_FRACTION:g} of master_period "
                               f"({MIN_SPAN_FRACTION * period:g})")
        slave_from = _number(raw, "from", where=where)
        if slave_from is not None:
            slave = slave_from  # a deliberate position jump; check() reports it
        stroke = _number(raw, "stroke", where=where)
        to = _number(raw, "to", where=where)
        if stroke is not None and to is not None:
            raise CamFileError(f"{where}: give at most one of 'stroke' or 'to'")
        if to is not None:
            stroke = to - slave
        if stroke is not None and not math.isfinite(stroke):
            raise CamFileError(f"{where}: stroke {stroke!r} (from {slave!r} to {to!r}) should be finite")
        name = raw.get("name", "")
        if not isinstance(name, str):
            raise CamFileError(f"{where}.name: {show(name)} should be a string")

        has_law, has_combo = "law" in raw, "combination" in raw
        if has_law == has_combo:
            raise CamFileError(f"{where}: give exactly one of 'law' or 'combination'")
        if has_combo:
            laws = raw["combination"]
            if not (isinstance(laws, list) and len(laws) == 2 and all(isinstance(x, str) for x in laws)):
                raise CamFileError(f"{where}.combination: {show(laws)} should be a list of two law names")
            ratio = _number(raw, "accel_ratio", where=where, required=True, positive=True)
            if stroke is None or stroke == 0:
                raise CamFileError(f"{where}.stroke: {show(stroke)} should be a non-zero number for a combination")
            try:
                pair = combination_segments(
                    laws[0], laws[1], master_start=master, span=span, slave_start=slave,
                    stroke=stroke, accel_ratio=ratio, name=name,
                )
            except InputError as exc:
                raise CamFileError(f"{where}.combination: {exc}") from None
            segments.extend(pair)
        else:
            law_name = raw["law"]
            if not isinstance(law_name, str):
                raise CamFileError(f"{where}.law: {show(law_name)} should be a law name (string)")
            if law_name == "dwell":
                if stroke not in (None, 0, 0.0):
                    raise CamFileError(f"{where}.stroke: {stroke!r} should be 0 or absent for a dwell")
                stroke = 0.0
                law_obj = _law("constant_velocity")
                name = name or "dwell"
            elif law_name in _POLYNOMIALS:
                law_obj = None  # solved below, once its neighbours are known
                pending_polynomials.append((len(segments), i, law_name, raw))
            else:
                try:
                    law_obj = _law(law_name)
                except InputError:
                    raise CamFileError(
                        f"{where}.law: {law_name!r} is unknown; expected 'dwell', 'poly5', 'poly7' "
                        f"or one of ecam.LAWS (see `ecam laws`)"
                    ) from None
            for key in _boundary_keys():
                if key in raw and law_name not in _POLYNOMIALS:
                    raise CamFileError(f"{where}.{key}: only poly5/poly7 segments take boundary conditions")
            if stroke is None:
                raise CamFileError(f"{where}.stroke: missing; expected a number (slave units) or 'to'")
            segments.append(Segment(master, master + span, slave, slave + stroke, law_obj, name))
        master += span
        slave += stroke

    for index, i, law_name, raw in pending_polynomials:
        segments[index] = _solve_polynomial(segments, index, i, law_name, raw, periodic)
    try:
        return CamProfile(
            tuple(segments),
            period,
            periodic,
            name=_string(data, "name", Path(source).stem),
            master_unit=_string(data, "master_unit", "deg"),
            slave_unit=_string(data, "slave_unit", "mm"),
            table=table,
        )
    except InputError as exc:
        raise CamFileError(str(exc)) from None


def _boundary_keys():
    return [f"{end}_{what}" for end in ("start", "end") for what in _BOUNDARY_KEYS]


def _solve_polynomial(segments, index, i, law_name, raw, periodic):
    """Solve a poly5/poly7 segment from its boundary conditions (user units), where the string
    'match' takes the value of the neighbouring segment (VDI 2143 motion-to-motion)."""
    where = f"segment[{i}]"
    seg = segments[index]
    if seg.stroke == 0:
        raise CamFileError(f"{where}.stroke: 0 -- a {law_name} segment needs a non-zero stroke")
    count = _POLYNOMIALS[law_name]
    normalized = {}
    for end in ("start", "end"):
        values = []
        for order, what in enumerate(_BOUNDARY_KEYS[:count], start=1):
            key = f"{end}_{what}"
            value = raw.get(key, 0.0)
            if value == "match":
                neighbour_index = index - 1 if end == "start" else index + 1
                if periodic:
                    neighbour_index %= len(segments)
                if not 0 <= neighbour_index < len(segments) or segments[neighbour_index].law is None:
                    raise CamFileError(f"{where}.{key}: 'match' needs a neighbouring segment with a fixed law")
                neighbour = segments[neighbour_index]
                value = neighbour.at(1.0 if end == "start" else 0.0, order)
            else:
                value = _number(raw, key, where=where, default=0.0)
            # user units -> normalized: d^k s/du^k = (d^k y/dx^k) * span^k / stroke
            try:
                normal = value * seg.span**order / seg.stroke
            except OverflowError:
                normal = math.inf
            if not math.isfinite(normal):
                raise CamFileError(f"{where}.{key}: {value!r} over a span of {seg.span!r} and a stroke of "
                                   f"{seg.stroke!r} should give a finite normalized value")
            values.append(normal)
        normalized[end] = values
        for key in (f"{end}_jerk",) if count == 2 else ():
            if key in raw:
                raise CamFileError(f"{where}.{key}: poly5 takes no jerk; use poly7")
    try:
        law_obj = polynomial_from_boundary(normalized["start"], normalized["end"], name=law_name)
    except InputError as exc:
        raise CamFileError(f"{where}: {exc}") from None
    return Segment(seg.master_start, seg.master_end, seg.slave_start, seg.slave_end, law_obj, seg.name)


def _table(raw) -> dict:
    if not isinstance(raw, dict):
        raise CamFileError(f"table: {show(raw)} should be a table ([table])")
    _unknown(raw, _TABLE_KEYS, "table.")
    out = {}
    if "interp" in raw:
        if raw["interp"] not in ("linear", "cubic", "quintic", "auto"):
            raise CamFileError(f"table.interp: {show(raw['interp'])} should be one of linear, cubic, quintic, auto")
        out["interp"] = raw["interp"]
    for key in ("points", "master_counts"):
        if key in raw:
            value = raw[key]
            if isinstance(value, bool) or not isinstance(value, int):
                raise CamFileError(f"table.{key}: {show(value)} should be an integer")
            out[key] = value
    if "tolerance" in raw:
        try:
            parse_tolerance(raw["tolerance"])
        except InputError as exc:
            raise CamFileError(f"table.{exc}") from None
        out["tolerance"] = raw["tolerance"]
    if "slave_counts_per_unit" in raw:
        out["slave_counts_per_unit"] = _number(raw, "slave_counts_per_unit", where="table", positive=True)
    return out


def _number(raw, key, *, where="", required=False, positive=False, default=None):
    prefix = f"{where}.{key}" if where else key
    if key not in raw:
        if required:
            raise CamFileError(f"{prefix}: missing; expected a number")
        return default
    value = raw[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CamFileError(f"{prefix}: {show(value)} should be a number")
    value = float(value)
    if not math.isfinite(value):
        raise CamFileError(f"{prefix}: {value!r} should be finite")
    if positive and not value > 0:
        raise CamFileError(f"{prefix}: {value!r} should be > 0")
    return value


def _boolean(raw, key, default):
    value = raw.get(key, default)
    if not isinstance(value, bool):
        raise CamFileError(f"{key}: {show(value)} should be true or false")
    return value


def _string(raw, key, default):
    value = raw.get(key, default)
    if not isinstance(value, str):
        raise CamFileError(f"{key}: {show(value)} should be a string")
    return value


def _unknown(raw, allowed, prefix):
    for key in raw:
        if key not in allowed:
            raise CamFileError(f"{prefix}{key}: unknown field; expected one of {', '.join(sorted(allowed))}")


def show(value) -> str:
    """A value for a one-line error message: its repr, cut to 60 characters."""
    text = repr(value)
    return text if len(text) < 60 else text[:57] + "..."
