"""Sphinx directives that generate ecam's reference pages from the code, so they cannot drift:

``{ecam-fields} MODULE``
    Every table of a file format's field table (``ecam.cam_fields``, ``hil_sim.scene_fields``):
    per table a heading, its description and one row per field with type, unit, default (and
    where it comes from), limits and meaning.
``{ecam-cli} PROGRAM``
    The ``ecam`` or ``hil-sim`` command line from its argparse parser: per subcommand its help,
    description and ``--help`` output.
"""

from __future__ import annotations

import importlib
import os
import re

from docutils import nodes
from docutils.parsers.rst import Directive

from ecam.field_table import format_default, format_limits

_CODE = re.compile(r"`([^`]+)`")


def _inline(text: str) -> list[nodes.Node]:
    """Text with `code` spans as literals."""
    out: list[nodes.Node] = []
    position = 0
    for match in _CODE.finditer(text):
        if match.start() > position:
            out.append(nodes.Text(text[position:match.start()]))
        out.append(nodes.literal(match.group(1), match.group(1)))
        position = match.end()
    if position < len(text):
        out.append(nodes.Text(text[position:]))
    return out


def _table(header: list[str], rows: list[list[str]], widths: list[int]) -> nodes.table:
    table = nodes.table(classes=["ecam-fields"])
    group = nodes.tgroup(cols=len(header))
    table += group
    for width in widths:
        group += nodes.colspec(colwidth=width)
    head = nodes.thead()
    group += head
    body = nodes.tbody()
    group += body
    for target, cells in ((head, [header]), (body, rows)):
        for cells_of_row in cells:
            row = nodes.row()
            for cell in cells_of_row:
                entry = nodes.entry()
                entry += nodes.paragraph("", "", *_inline(cell))
                row += entry
            target += row
    return table


def _literal(text: str) -> nodes.literal_block:
    """A block of command output, shown as written (no highlighting)."""
    block = nodes.literal_block(text.rstrip(), text.rstrip())
    block["language"] = "text"
    return block


def _anchor(prefix: str, table: str) -> str:
    return nodes.make_id(f"{prefix}-{table or 'top-level'}")


class FieldsDirective(Directive):
    """``{ecam-fields} MODULE``: the module's ``*_FIELDS`` and ``*_TABLES`` as tables."""

    required_arguments = 1

    def run(self):
        module = importlib.import_module(self.arguments[0])
        fields = next(getattr(module, name) for name in module.__all__ if name.endswith("_FIELDS"))
        tables = next(getattr(module, name) for name in module.__all__ if name.endswith("_TABLES"))
        prefix = self.arguments[0].rsplit(".", 1)[-1].replace("_", "-")
        out = []
        for table, text in tables.items():
            title = "top level" if not table else (f"[[{table}]]" if table == "segment" else f"[{table}]")
            rubric = nodes.rubric(title, title, ids=[_anchor(prefix, table)])
            out.append(rubric)
            out.append(nodes.paragraph("", "", *_inline(text)))
            rows = []
            for field in fields:
                if field.table != table:
                    continue
                default = format_default(field)
                if field.source and field.default is not None or field.source and field.default_text:
                    default += f" (from {field.source})"
                rows.append([f"`{field.key}` ({field.kind})", field.unit or "-", default,
                             format_limits(field), field.description])
            out.append(_table(["field", "unit", "default (source)", "limits", "meaning"], rows,
                              [18, 10, 22, 20, 30]))
        return out


class CliDirective(Directive):
    """``{ecam-cli} ecam`` or ``{ecam-cli} hil-sim``: every subcommand's ``--help``."""

    required_arguments = 1

    def run(self):
        from ecam.app import cli  # the application layer: read here, imported by nothing

        parser = cli.build_parser() if self.arguments[0] == "ecam" else cli.build_hil_sim_parser()
        saved = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width: fix it
        try:
            out = [_literal(parser.format_help())]
            actions = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
            for action in actions:
                helps = {choice.dest: choice.help for choice in action._choices_actions}
                for name, sub in action.choices.items():
                    title = f"{parser.prog} {name}"
                    out.append(nodes.rubric(title, title, ids=[nodes.make_id(title)]))
                    if helps.get(name):
                        out.append(nodes.paragraph("", "", *_inline(helps[name])))
                    out.append(_literal(sub.format_help()))
        finally:
            if saved is None:
                del os.environ["COLUMNS"]
            else:
                os.environ["COLUMNS"] = saved
        return out


def setup(app):
    app.add_directive("ecam-fields", FieldsDirective)
    app.add_directive("ecam-cli", CliDirective)
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}
