"""Text from a cam file (its name, its units) made safe for each export's comment and header syntax.

A cam file's names and units are refused where they are read if they hold control characters
(:func:`ecam.validate.text`), so no line break reaches an export. What remains are the printable
characters a format gives a meaning: each exporter passes the user's text through the function of
its format here, where it writes it, so a name can never end a comment or add a column.
"""

from __future__ import annotations

import unicodedata

__all__ = ["iec_comment", "line_comment", "csv_field"]


def iec_comment(text: str) -> str:
    """``text`` for the inside of an IEC 61131-3 comment ``(* ... *)``.

    IEC 61131-3:2013, 6.1.5 and Table 2 (features 2a, 2b, 3a, 3b): a comment is delimited by
    ``(*`` and ``*)`` or by ``/*`` and ``*/``, and comments of the same kind may nest, so both the
    closing and the opening delimiters of both kinds are broken up: a space goes between every
    ``*`` and a ``(`` or ``/`` before it and a ``)`` or ``/`` after it (``*)`` -> ``* )``,
    ``(*`` -> ``( *``). ``//`` starts a comment only outside one and needs nothing. Line ends
    stay (the comment spans lines); other control characters are escaped.
    """
    chars = _printable(text, keep="\n")  # a (* *) comment spans lines: only its delimiters matter
    out = []
    for index, char in enumerate(chars):
        if char == "*":
            if index and chars[index - 1] in ("(", "/"):
                out.append(" ")
            out.append(char)
            if index + 1 < len(chars) and chars[index + 1] in (")", "/"):
                out.append(" ")
        else:
            out.append(char)
    return "".join(out)


def line_comment(text: str) -> str:
    """``text`` for a comment that runs to the end of its line (``# ...`` in the ISG table
    format and in ecam's CSV): nothing in it may end the line."""
    return "".join(_printable(text))


def csv_field(text: str) -> str:
    """``text`` as one CSV field: RFC 4180, section 2, rules 6 and 7 (a field holding a comma, a
    double quote or a line break is enclosed in double quotes, and a double quote in it is
    written twice)."""
    text = "".join(_printable(text))
    if any(char in text for char in ',"\r\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


def _printable(text: str, keep: str = "") -> list[str]:
    """The characters of ``text``, each line break or other control character (Unicode Cc, Zl,
    Zp) but those in ``keep`` replaced by its Python escape (``\\n``, ``\\x00``, ``\\u2028``)."""
    return [ascii(char)[1:-1] if unicodedata.category(char) in ("Cc", "Zl", "Zp") and char not in keep
            else char for char in text]
