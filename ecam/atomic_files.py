"""Writing output files so that a crash, a full disk or a kill never leaves a half-written one.

Used by the command line and the firmware generator (the library itself returns text and bytes
and writes nothing). Each file is written to a temporary file in its own directory, flushed to
disk, and renamed over the target; a group of files (a table's .h, .bin, .json ...) is renamed
only once every member has been written, so they appear together or not at all. An output that
is a symbolic link is replaced by the new file, never followed: its target is left untouched.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["write_files"]


def write_files(contents: dict) -> None:
    """Write ``{path: text or bytes}`` atomically, as one group.

    Raises
    ------
    OSError
        From creating, writing or renaming; the files already at those paths are then intact
        and no temporary file is left behind.
    """
    staged: list[tuple[str, Path]] = []
    try:
        for path, content in contents.items():
            path = Path(path)
            data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
            fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
            staged.append((temporary, path))
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
            os.chmod(temporary, 0o644)  # mkstemp makes 0600; outputs are ordinary files
        for temporary, path in staged:
            os.replace(temporary, path)
    except BaseException:
        for temporary, _ in staged:
            try:
                os.unlink(temporary)
            except FileNotFoundError:
                pass
        raise
