"""The one way `ecam sim` prints a run's report, for a scene and for a machine alike: JSON (with
the search's result under ``max_speed``) or text (with the search's text after it)."""

from __future__ import annotations

import argparse
import json
import sys


def print_report(args: argparse.Namespace, report, search, format_search) -> None:
    """Print ``report`` (a scene's or a machine's) as ``--json`` asks, with ``search`` (a
    ``--find-max-speed`` result or None) formatted by ``format_search`` in the text."""
    if args.json:
        out = report.to_dict(timing=args.timing)
        if search is not None:
            out["max_speed"] = search
        print(json.dumps(out, indent=2, sort_keys=True, allow_nan=False))
    else:
        sys.stdout.write(report.to_text())
        if search is not None and format_search is not None:
            sys.stdout.write(format_search(search))
