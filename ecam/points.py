"""Point tables for :func:`ecam.fit_points`: a user's text table, ecam's CSV export, a CODESYS XYVA
cam.

* **A text table**: two or three columns -- master, slave, optionally a weight -- separated by
  commas, semicolons, tabs or spaces, in the user's units. Blank lines and comments (from ``#``,
  ``//`` or ``;`` at the start of a line, or ``#`` after the numbers) are skipped, and so is one
  header line of names before the numbers.
* **ecam's CSV export** (:mod:`ecam.export.csv_points`): recognized by its first comment; its
  header line gives the units, the master period, whether the cam is periodic and its net stroke,
  and its columns velocity and acceleration where the interpolation carries them.
* **A CODESYS XYVA cam** (:mod:`ecam.export.codesys`, the global variable list of
  ``SMC_CAMXYVA`` points ``(dX := .., dY := .., dV := .., dA := ..)``).

A table that carries velocities (and accelerations) describes a curve between its rows, the one
its controller runs: the cubic (quintic) Hermite polynomial through both rows' values (the rule
of ecam's CSV, and of CODESYS XYVA: one fifth-degree polynomial per interval through both points'
Y, V and A). :meth:`PointTable.samples` gives that curve sampled inside every interval, so the fit
follows what the controller did, not just the rows.

Reads are bounded (:data:`MAX_POINTS_BYTES`); every refusal is one line naming the file, the line
and what was expected.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .camfile import read_bounded
from .errors import InputError
from .export.certify import Hermite
from .validate import show, show_path

__all__ = ["PointTable", "read_points", "parse_points", "MAX_POINTS_BYTES", "SAMPLES_PER_INTERVAL"]

# A table of 10^6 rows of two numbers is about 30 MB; beyond this a path is not a point table.
MAX_POINTS_BYTES = 64 * 2**20
# Samples of a Hermite table's curve inside each of its intervals (its rows included), and at most
# this many in all.
SAMPLES_PER_INTERVAL = 64
MAX_SAMPLES = 200_000
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_XYVA = re.compile(r"\(\s*dX\s*:=\s*(" + _NUMBER + r")\s*,\s*dY\s*:=\s*(" + _NUMBER + r")\s*,\s*dV\s*:=\s*("
                   + _NUMBER + r")\s*,\s*dA\s*:=\s*(" + _NUMBER + r")\s*\)")
_SEPARATORS = re.compile(r"[,;\t ]+")


@dataclass(frozen=True)
class PointTable:
    """Points read from a file.

    Attributes
    ----------
    master, slave : ndarray
        The rows, user units.
    weights : ndarray or None
        The third column, when there is one.
    lines : ndarray
        The line of the file each row came from (1-based), for messages.
    kind : str
        ``"table"``, ``"ecam-csv"`` or ``"codesys-xyva"``.
    derivatives : ndarray or None
        Velocity (and acceleration) per row, when the file carries them: shape (rows, 1 or 2).
    settings : dict
        What the file says of the cam (ecam's CSV: ``periodic``, ``net_stroke``, ``master_period``,
        ``master_unit``, ``slave_unit``).
    """

    master: np.ndarray
    slave: np.ndarray
    weights: np.ndarray | None
    lines: np.ndarray
    kind: str
    derivatives: np.ndarray | None = None
    settings: dict | None = None

    @property
    def interpolation(self) -> str | None:
        """The Hermite degree the file's rows are joined by: 'cubic', 'quintic', or None."""
        if self.derivatives is None:
            return None
        return "cubic" if self.derivatives.shape[1] == 1 else "quintic"

    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The curve the table describes: for a table with derivatives, its Hermite polynomials
        sampled ``SAMPLES_PER_INTERVAL`` times per interval (fewer when the rows are many; the
        rows always); else the rows themselves."""
        if self.derivatives is None:
            return self.master, self.slave
        x = self.master
        if np.any(np.diff(x) <= 0):
            i = int(np.flatnonzero(np.diff(x) <= 0)[0]) + 1
            raise InputError(f"master: {x[i]:.10g} on line {self.lines[i]} should be greater than {x[i - 1]:.10g} "
                             "(the line before): a table with velocities needs increasing master positions")
        per = max(1, min(SAMPLES_PER_INTERVAL, MAX_SAMPLES // max(x.size - 1, 1)))
        degree = 3 if self.derivatives.shape[1] == 1 else 5
        data = np.column_stack([self.slave, self.derivatives])
        curve = Hermite.continuous(x, degree, data)
        t = np.arange(per) / per
        interval = np.repeat(np.arange(x.size - 1), per)
        tt = np.tile(t, x.size - 1)
        master = np.append(x[interval] + tt * curve.widths[interval], x[-1])
        slave = np.append(curve.at(interval, tt), self.slave[-1])
        return master, slave


def read_points(path) -> PointTable:
    """Read a point table (module docstring) from ``path``: at most :data:`MAX_POINTS_BYTES`, a
    regular file.

    Raises
    ------
    InputError
        A missing, unreadable, irregular or oversized file, or text that is not a point table.
    """
    path = Path(path)
    shown = show_path(path)
    # camfile's bounded, non-blocking read (CamFileError is an InputError): one reader of users' files
    data = read_bounded(path, "points", MAX_POINTS_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"points {shown} should be UTF-8 text: {exc.reason} at byte {exc.start}") from None
    return parse_points(text, source=shown)


def parse_points(text: str, source: str = "<points>") -> PointTable:
    """A :class:`PointTable` from the text of a point file (module docstring)."""
    if "SMC_CAMXYVA" in text:
        return _codesys(text, source)
    if text.startswith("# Generated by ecam (vendor export"):
        return _ecam_csv(text, source)
    return _table(text, source)


def _table(text: str, source: str) -> PointTable:
    rows, lines = [], []
    header_seen = False
    width = None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith(("#", "//", ";")):
            continue
        stripped = stripped.split("#", 1)[0].strip()
        cells = [c for c in _SEPARATORS.split(stripped) if c]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows and not header_seen:
                header_seen = True  # one line of column names before the numbers
                continue
            bad = next(c for c in cells if not _is_number(c))
            raise InputError(f"points {source} line {number}: {show(bad)} should be a number") from None
        if width is None:
            width = len(values)
            if width not in (2, 3):
                raise InputError(f"points {source} line {number}: {width} columns should be 2 or 3 "
                                 "(master, slave, optionally a weight)")
        elif len(values) != width:
            raise InputError(f"points {source} line {number}: {len(values)} columns should be {width}, as on "
                             f"line {lines[0]}")
        rows.append(values)
        lines.append(number)
    if not rows:
        raise InputError(f"points {source}: no rows of numbers; expected lines of master, slave[, weight]")
    array = np.array(rows, dtype=float)
    bad = ~np.isfinite(array)
    if bad.any():
        row, column = (int(v[0]) for v in np.nonzero(bad))
        raise InputError(f"points {source} line {lines[row]}: {float(array[row, column])!r} should be a finite number")
    return PointTable(array[:, 0], array[:, 1], array[:, 2] if width == 3 else None,
                      np.array(lines), "table")


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _ecam_csv(text: str, source: str) -> PointTable:
    settings = {}
    body = []  # (line number, text) of the lines that are not comments
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("# master_unit:"):
            for item in line[1:].split(";"):
                key, _, value = item.partition(":")
                settings[key.strip()] = value.strip()
        elif not line.startswith("#"):
            body.append((number, line))
    # master, slave, then velocity and acceleration where the interpolation carries them
    array, lines = _numbers_of(body, source)
    parsed = {}
    try:
        if "periodic" in settings:
            parsed["periodic"] = settings["periodic"] == "yes"
        if "net_stroke" in settings:
            parsed["net_stroke"] = float(settings["net_stroke"])
        if "master_period" in settings:
            parsed["master_period"] = float(settings["master_period"])
    except ValueError:
        raise InputError(f"points {source}: the header line '# master_unit: ...' should hold numbers for "
                         "master_period and net_stroke") from None
    for key in ("master_unit", "slave_unit"):
        if key in settings:
            parsed[key] = settings[key]
    derivatives = array[:, 2:] if array.shape[1] > 2 else None
    return PointTable(array[:, 0], array[:, 1], None, lines, "ecam-csv", derivatives, parsed)


def _numbers_of(body, source) -> tuple[np.ndarray, np.ndarray]:
    rows, lines = [], []
    width = None
    for number, line in body:
        if not line.strip():
            continue
        cells = line.strip().split(",")
        if not all(_is_number(c) for c in cells):
            if rows:
                raise InputError(f"points {source} line {number}: {show(line)} should be numbers")
            continue  # the column names
        if width is None:
            width = len(cells)
            if width not in (2, 3, 4):
                raise InputError(f"points {source} line {number}: {width} columns should be 2 to 4 "
                                 "(master, slave, velocity, acceleration)")
        elif len(cells) != width:
            raise InputError(f"points {source} line {number}: {len(cells)} columns should be {width}")
        rows.append([float(c) for c in cells])
        lines.append(number)
    if not rows:
        raise InputError(f"points {source}: no rows of numbers")
    array = np.array(rows)
    if not np.isfinite(array).all():
        raise InputError(f"points {source}: every value should be a finite number")
    return array, np.array(lines)


def _codesys(text: str, source: str) -> PointTable:
    rows, lines = [], []
    for number, line in enumerate(text.splitlines(), start=1):
        for match in _XYVA.finditer(line):
            rows.append([float(v) for v in match.groups()])
            lines.append(number)
    if not rows:
        raise InputError(f"points {source}: a CODESYS cam without (dX := .., dY := .., dV := .., dA := ..) points")
    array = np.array(rows)
    if not np.isfinite(array).all():
        raise InputError(f"points {source}: every dX, dY, dV, dA should be a finite number")
    return PointTable(array[:, 0], array[:, 1], None, np.array(lines), "codesys-xyva", array[:, 2:4], {})
