"""Declarative tables of the fields a file format accepts: name, type, unit, default, limits and
where the default comes from.

The cam file's table is :data:`ecam.cam_fields.CAM_FIELDS`, the scene file's
:data:`hil_sim.scene_fields.SCENE_FIELDS`. The documentation's reference pages are generated from
them, and ``tests/test_field_tables.py`` holds them to the parsers: every key a parser accepts has
a row, and every row's numeric limits are the ones the parser enforces (the value at a limit is
accepted, a value past it refused with a message naming the field). Adding a field to a parser
means adding its row here; the test says which one is missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Field", "REQUIRED", "format_limits", "format_default"]

#: The ``default`` of a field the file must give.
REQUIRED = "required"


@dataclass(frozen=True)
class Field:
    """One field of a file format.

    Parameters
    ----------
    table : str
        The dotted table the field sits in: ``""`` for the top level, ``"drive.gains"``,
        ``"segment"`` for an array of tables (``[[segment]]``).
    key : str
        The field's name in the file.
    kind : str
        Its TOML type in words: ``"number"``, ``"integer"``, ``"string"``, ``"boolean"``,
        ``"choice"``, ``"table"``, ``"array"``, or an alternative such as ``"number or string"``.
    description : str
        What it means, one or two sentences.
    unit : str
        Its unit (``"s"``, ``"N m"``, ``"master units"``); empty for none.
    default : object
        The value taken when the field is left out; :data:`REQUIRED` when it must be given;
        ``None`` for an optional field whose absence means "none" (see ``default_text``).
    default_text : str
        The default in words, where it is computed (``"1 % of the motor torque limit"``) or
        where absence means something (``"no limit"``).
    source : str
        Where the default comes from: the module that holds it, a catalogue, a standard.
    minimum, maximum : float or None
        The limits the parser enforces (inclusive unless ``exclusive_minimum``).
    exclusive_minimum : bool
        The value must be strictly above ``minimum``.
    choices : tuple of str
        The accepted strings of a ``"choice"`` field.
    limits : str
        Rules beyond the range, in words (``"points - 1 divides master_counts"``).
    when : tuple of (str, object)
        Other fields this one needs to apply, as (dotted name, value) pairs
        (``(("master.profile", "start_stop"),)``); the test sets them before probing the limits.
    probe : bool
        False where the limits depend on other fields in a way the generic probe cannot set up;
        ``limits`` then says the rule.
    """

    table: str
    key: str
    kind: str
    description: str
    unit: str = ""
    default: object = None
    default_text: str = ""
    source: str = ""
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    choices: tuple[str, ...] = ()
    limits: str = ""
    when: tuple[tuple[str, object], ...] = ()
    probe: bool = True

    @property
    def name(self) -> str:
        """The dotted name, as the parsers' messages write it (``drive.cycle_s``)."""
        return f"{self.table}.{self.key}" if self.table else self.key


def _number(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e5:
        return repr(value)
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, int) and value >= 2**16 and value & (value - 1) == 0:
        return f"{value} (2^{value.bit_length() - 1})"
    return repr(value) if isinstance(value, str) else str(value)


def format_default(field: Field) -> str:
    """The default as the reference shows it."""
    if field.default == REQUIRED:
        return "required"
    parts = []
    if field.default is not None:
        parts.append(f'"{field.default}"' if isinstance(field.default, str) else _number(field.default))
    if field.default_text:
        parts.append(field.default_text)
    return "; ".join(parts) or "none"


def format_limits(field: Field) -> str:
    """The limits as the reference shows them (``1e-05 .. 0.255``, ``> 0``, ``one of ...``)."""
    parts = []
    if field.choices:
        parts.append("one of " + ", ".join(f'"{c}"' for c in field.choices))
    low, high = field.minimum, field.maximum
    if low is not None and high is not None and not field.exclusive_minimum:
        parts.append(f"{_number(low)} .. {_number(high)}")
    else:
        if low is not None:
            parts.append(f"{'>' if field.exclusive_minimum else '>='} {_number(low)}")
        if high is not None:
            parts.append(f"<= {_number(high)}")
    if field.kind in ("number", "integer") and low is None and high is None and not field.limits:
        parts.append("finite")
    if field.limits:
        parts.append(field.limits)
    return "; ".join(parts) or "-"


def check_probe_values(field: Field) -> list[tuple[object, bool]]:
    """Values to try for ``field`` and whether the parser should accept each: the limits
    themselves and just past them. Empty for a field without numeric limits."""
    if not field.probe or field.kind not in ("number", "integer"):
        return []
    out = []
    integer = field.kind == "integer"
    if field.minimum is not None:
        low = field.minimum
        out.append((int(low) if integer else float(low), not field.exclusive_minimum))
        past = low - 1 if integer else low - max(abs(low), 1e-300) * 1e-3
        if not integer and low == 0.0:
            past = -1e-3
        out.append((int(past) if integer else float(past), False))
    if field.maximum is not None:
        high = field.maximum
        out.append((int(high) if integer else float(high), True))
        past = high + 1 if integer else high + abs(high) * 1e-3
        out.append((int(past) if integer else float(past), False))
    return [(value, ok) for value, ok in out if integer or math.isfinite(value)]
