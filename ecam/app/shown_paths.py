"""Paths as a report page shows them: relative to the working directory, from the package on for a
file shipped with ecam (``hil_sim/scenes/knife.toml``), else the file's name.

An HTML report is a CI artifact read on another machine, where an absolute path
(``/usr/lib/python3/site-packages/hil_sim/scenes/...``, a runner's build directory) names nothing
the reader has and tells about the machine that wrote it. Relative to the working directory, a
path reads as the user typed it, and the page's bytes do not depend on where ecam is installed.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["shown_path", "shown_text"]

# The directory that holds the ecam and hil_sim packages: a checkout, or site-packages.
INSTALL_ROOT = Path(__file__).resolve().parents[2]


def _bases() -> list[Path]:
    # The working directory first: a user's file inside it reads as they typed it.
    return [Path(os.path.abspath(os.getcwd())), INSTALL_ROOT]


def shown_path(path) -> str:
    """``path`` for a report: as given when relative, else relative to the working directory or
    to the installed packages' directory, else its file name only."""
    path = Path(path)
    if not path.is_absolute():
        return str(path)
    path = Path(os.path.normpath(path))
    for base in _bases():
        if path.is_relative_to(base) and path != base:
            return str(path.relative_to(base))
    return path.name


def shown_text(text: str) -> str:
    """``text`` (an error message, a traceback) with the working directory's and the installed
    packages' absolute prefixes left out, so the paths in it read as :func:`shown_path` shows them."""
    text = str(text)
    for base in _bases():
        if str(base) != os.sep:
            text = text.replace(str(base) + os.sep, "")
    return text
