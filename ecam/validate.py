"""The one validation path: every value a user hands to ecam or hil_sim comes through here.

Cam files, scene files, table settings, mechanics and the Python API all check their inputs with
these functions, so every refusal has the same shape, one line::

    <field>: <value> should be <what was expected>

``field`` is the dotted name the user wrote (``segment[2].span``, ``mechanics.gear_ratio``,
``tolerance``); ``value`` is shown by :func:`show`, cut to 60 characters so a hostile value cannot
flood a terminal. A :class:`Fields` reader adds the file it reads from as a prefix and raises
:class:`~ecam.errors.CamFileError`; the plain functions raise :class:`~ecam.errors.InputError`.
Both derive from ``ValueError``.
"""

from __future__ import annotations

import decimal
import math
import unicodedata
from collections.abc import Callable, Iterable, Mapping
from contextlib import contextmanager

import numpy as np

from .errors import CamFileError, InputError

# Largest magnitude any user number may have: far beyond every physical quantity here, small
# enough that a product of two of them (1e300) stays finite in float64.
MAX_MAGNITUDE = 1e150


def show(value) -> str:
    """A value for a one-line error message: its repr, cut to 60 characters."""
    if isinstance(value, float) and math.isfinite(value):
        text = f"{value:.12g}"
    elif isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**15:
        try:
            text = f"{value:.6g}"
        except OverflowError:  # past float's range: the same form, from the exact integer
            mantissa, _, exponent = format(decimal.Decimal(value), ".6g").partition("e")
            text = f"{mantissa.rstrip('0').rstrip('.')}e{exponent}"
    else:
        text = repr(value)
    return text if len(text) < 60 else text[:57] + "..."


def show_path(path) -> str:
    """A file's path for a one-line error message: its repr, cut in the middle to 60
    characters, so that a long directory never hides the file's own name."""
    text = repr(str(path))
    return text if len(text) < 60 else text[:19] + "..." + text[-38:]


def fail(field: str, value, expected: str, error=InputError) -> InputError:
    """The error for ``field`` holding ``value`` where ``expected`` was wanted (not raised).

    The error remembers ``field`` (as ``error.field``), so a reader can rename it, see
    :func:`renamed`.
    """
    return _with_field(error(f"{field}: {show(value)} should be {expected}"), field)


def missing(field: str, expected: str, error=InputError) -> InputError:
    """The error for a required ``field`` that is absent (not raised)."""
    return _with_field(error(f"{field}: missing; expected {expected}"), field)


def _with_field(exc, field: str):
    exc.field = field
    return exc


def renamed(exc: Exception, rename: Callable[[str], str], error=InputError) -> InputError:
    """``exc`` again, as an ``error``, with its field renamed by ``rename`` (not raised).

    A reader hands values to the Python API, whose messages name the API's parameters
    (``segment[2].master_start``); ``rename`` maps them onto the reader's own field names
    (``segment[2].start``). A message that names no field keeps its text.
    """
    text = str(exc)
    field = getattr(exc, "field", None)
    if isinstance(field, str) and text.startswith(field + ":"):
        return _with_field(error(rename(field) + text[len(field):]), rename(field))
    return error(text)


def plain(value):
    """``value``, or the Python number a numpy scalar holds (``numpy.int64(3)`` -> ``3``).

    The checks here take Python numbers only (a ``numpy.float32`` is no ``float``); a caller
    whose values may come out of numpy arithmetic passes them through this first.
    """
    return value.item() if isinstance(value, np.generic) else value


def number(field: str, value, *, minimum=None, maximum=None, strict: bool = False,
           error=InputError) -> float:
    """``value`` as a finite float within ``[minimum, maximum]``.

    ``strict`` makes the lower bound exclusive (``> minimum``). Without an explicit bound the
    magnitude is still limited to :data:`MAX_MAGNITUDE`, so arithmetic on it stays finite.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise fail(field, value, "a number", error)
    try:
        result = float(value)
    except OverflowError:  # an int too large for a float
        raise fail(field, value, f"a number of magnitude <= {MAX_MAGNITUDE:g}", error) from None
    if not math.isfinite(result):
        raise fail(field, value, "finite", error)
    if minimum is not None and (result <= minimum if strict else result < minimum):
        raise fail(field, value, f"{'>' if strict else '>='} {minimum:g}", error)
    if maximum is not None and result > maximum:
        raise fail(field, value, f"<= {maximum:g}", error)
    if abs(result) > MAX_MAGNITUDE:
        raise fail(field, value, f"of magnitude <= {MAX_MAGNITUDE:g}", error)
    return result


def positive(field: str, value, *, maximum=None, error=InputError) -> float:
    """``value`` as a finite float > 0."""
    return number(field, value, minimum=0.0, strict=True, maximum=maximum, error=error)


def integer(field: str, value, *, minimum=None, maximum=None, error=InputError) -> int:
    """``value`` as an int (not a bool, not a float) within ``[minimum, maximum]``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise fail(field, value, "an integer", error)
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        if maximum is None:
            bounds = f">= {minimum}"
        elif minimum is None:
            bounds = f"<= {maximum}"
        else:
            bounds = f"in {minimum}..{maximum}"
        raise fail(field, value, f"an integer {bounds}", error)
    return value


def choice(field: str, value, choices: Iterable[str], error=InputError) -> str:
    """``value``, which must be one of ``choices``."""
    choices = tuple(choices)
    if not isinstance(value, str) or value not in choices:
        raise fail(field, value, f"one of {', '.join(choices)}", error)
    return value


def boolean(field: str, value, error=InputError) -> bool:
    """``value``, which must be ``True`` or ``False``."""
    if not isinstance(value, bool):
        raise fail(field, value, "true or false", error)
    return value


def string(field: str, value, error=InputError) -> str:
    """``value``, which must be a string."""
    if not isinstance(value, str):
        raise fail(field, value, "a string", error)
    return value


#: Longest name (of a cam, a segment, a scene) [characters]: a line of a report, not a file;
#: as long as a file name may be (POSIX NAME_MAX on Linux), since a name defaults to its file's.
MAX_NAME_CHARS = 255
#: Longest unit [characters] ("deg", "mm", "rev", "counts", ...).
MAX_UNIT_CHARS = 32
#: Longest free text (a scene's description) [characters].
MAX_DESCRIPTION_CHARS = 4000
# The bidirectional embedding, override and isolate controls (Unicode UAX #9, table 1: LRE RLE
# PDF LRO RLO, LRI RLI FSI PDI): in a generated file they make a comment display as code and
# code as a comment ("Trojan Source", CVE-2021-42574).
_BIDI_CONTROLS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def text(field: str, value, *, maximum: int = MAX_NAME_CHARS, error=InputError) -> str:
    """``value``, a string of at most ``maximum`` characters without control characters.

    Names and units go into exported files (comments of IEC 61131-3 source, CSV headers, ISG
    tables, JUnit XML), plots and one-line messages: a line break there ends a comment or a
    row, a NUL or an ESC garbles a terminal, XML 1.0 has no encoding for most C0 characters.
    Refused: Unicode category Cc (C0, DEL, C1) but the tab, which is white space everywhere
    these go, the line and paragraph separators (Zl, Zp) and the bidirectional controls.
    """
    string(field, value, error)
    if len(value) > maximum:
        raise fail(field, value, f"a text of at most {maximum} characters ({len(value)} given)", error)
    for index, char in enumerate(value):
        if (unicodedata.category(char) in ("Cc", "Zl", "Zp") and char != "\t") or char in _BIDI_CONTROLS:
            raise fail(field, value, f"a text without control characters ({ascii(char)} at {index})",
                       error)
    return value


class Fields:
    """Reads the fields of one TOML table (or a nested table of it) with one-line errors.

    Parameters
    ----------
    raw : mapping
        The parsed table.
    where : str
        Its dotted name in the file (``""`` at the top level, ``"mechanics"``, ``"segment[2]"``).
    source : str
        The file, as shown to the user; it prefixes every message (``scene x.toml: ...``).
    allowed : iterable of str, optional
        The field names this table may hold; any other is refused, naming the allowed ones.
    """

    def __init__(self, raw, where: str = "", source: str = "", allowed=None) -> None:
        self.where = where
        self.source = source
        if not isinstance(raw, Mapping):
            raise self.error(f"{where or 'file'}: {show(raw)} should be a table ([{where}])")
        self.raw = raw
        if allowed is not None:
            for key in raw:
                if key not in allowed:
                    # A key is the user's text: shown quoted and cut where it is not a plain name
                    # (a newline in it would make the message two lines).
                    written = key if isinstance(key, str) and key.isidentifier() and len(key) < 60 else show(key)
                    raise self.error(f"{self.name(written)}: unknown field; expected one of "
                                     f"{', '.join(sorted(allowed))}")

    def error(self, message: str) -> CamFileError:
        """A :class:`CamFileError` for ``message``, prefixed with the source file."""
        return CamFileError(f"{self.source}: {message}" if self.source else message)

    def name(self, key: str) -> str:
        """The dotted name of ``key`` in this table."""
        return f"{self.where}.{key}" if self.where else key

    def __contains__(self, key: str) -> bool:
        return key in self.raw

    def _get(self, key: str, required: bool, expected: str):
        if key not in self.raw:
            if required:
                raise self.error(f"{self.name(key)}: missing; expected {expected}")
            return None
        return self.raw[key]

    def _checked(self, check, key, *args, **kwargs):
        try:
            return check(self.name(key), *args, **kwargs)
        except InputError as exc:
            raise self.error(str(exc)) from None

    def table(self, key: str, allowed=None, required: bool = False) -> "Fields":
        """The nested table ``key`` as a reader (empty when absent and not required)."""
        value = self._get(key, required, "a table")
        if value is None:
            value = {}
        if not isinstance(value, Mapping):
            raise self.error(f"{self.name(key)}: {show(value)} should be a table "
                             f"([{self.name(key)}])")
        return Fields(value, self.name(key), self.source, allowed)

    def number(self, key: str, *, required=False, default=None, minimum=None, maximum=None,
               strict=False):
        value = self._get(key, required, "a number")
        if value is None:
            return default
        return self._checked(number, key, value, minimum=minimum, maximum=maximum, strict=strict)

    def integer(self, key: str, *, required=False, default=None, minimum=None, maximum=None):
        value = self._get(key, required, "an integer")
        if value is None:
            return default
        return self._checked(integer, key, value, minimum=minimum, maximum=maximum)

    def choice(self, key: str, choices, default=None, required=False):
        value = self._get(key, required, f"one of {', '.join(choices)}")
        if value is None:
            return default
        return self._checked(choice, key, value, choices)

    def boolean(self, key: str, default=None, required=False):
        value = self._get(key, required, "true or false")
        if value is None:
            return default
        return self._checked(boolean, key, value)

    def string(self, key: str, default=None, required=False):
        value = self._get(key, required, "a string")
        if value is None:
            return default
        return self._checked(string, key, value)

    def text(self, key: str, default=None, required=False, maximum: int = MAX_NAME_CHARS):
        """A name, unit or description: see :func:`text`."""
        value = self._get(key, required, "a string")
        if value is None:
            return default
        return self._checked(text, key, value, maximum=maximum)

    @contextmanager
    def calling(self, rename: Callable[[str], str] | None = None):
        """Run a call into the Python API: an :class:`InputError` it raises becomes this file's
        error, its field renamed by ``rename`` (default: placed inside this table)."""
        try:
            yield
        except CamFileError:
            raise
        except InputError as exc:
            raise self.error(str(renamed(exc, rename or self.name))) from None

    def get(self, key: str, default=None):
        """The raw value of ``key`` (for fields with a shape of their own)."""
        return self.raw.get(key, default)
