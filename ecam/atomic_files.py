"""Writing output files so that a crash, a full disk or a kill never leaves a half-written one.

Used by the command line and the firmware generator (the library itself returns text and bytes
and writes nothing). Each file is written to a temporary file in its own directory, flushed to
disk, and renamed over the target; a group of files (a table's .h, .bin, .json ...) is renamed
only once every member has been written, so they appear together or not at all. An output that
is a symbolic link to a regular file is replaced by the new file, never followed: its target is
left untouched.

What an output must never replace is refused first, in one line (:func:`check_outputs`): a
device node, FIFO, socket or directory (``-o /dev/null`` as root made the device a regular
file), a symbolic link to one of those or to a process's open file (``--junit /dev/stdout``,
a link to ``/proc/self/fd/1``: a stream, though it may name a regular file while the output is
redirected), and the command's own input files (``ecam export cam.toml -o cam.toml``), which
the rename would silently replace.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

from .errors import InputError
from .validate import show

__all__ = ["write_files", "check_outputs"]

_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a directory"))


def check_outputs(paths, inputs=()) -> None:
    """Refuse outputs that writing would destroy or that cannot be written (one line each).

    Parameters
    ----------
    paths : iterable of path
        The files a command is about to write.
    inputs : iterable of path
        The files it reads (a cam, a scene and its cam): none may be an output, by its own name
        or by another name of the same file (a hard link, a symbolic link named as input).

    Raises
    ------
    InputError
        ``output <path>: ...`` naming why: a device node, FIFO, socket or directory, a symbolic
        link to one (or a link loop), an input file, or a path the system refuses to look at
        (a component longer than NAME_MAX, 255 bytes on Linux: ENAMETOOLONG).
    """
    taken = {}
    for item in inputs:
        for look in (os.stat, os.lstat):
            try:
                info = look(item)
            except (OSError, ValueError):
                continue
            taken[(info.st_dev, info.st_ino)] = item
    for path in paths:
        shown = show(str(path))
        try:
            here = os.lstat(path)
        except FileNotFoundError:
            continue  # a new file (a missing directory is the write's to report)
        except (OSError, ValueError) as exc:
            reason = getattr(exc, "strerror", None) or str(exc)
            raise InputError(f"output {shown} cannot be used: {reason}") from None
        target = here
        if stat.S_ISLNK(here.st_mode):
            try:
                target = os.stat(path)
            except FileNotFoundError:
                target = None  # a dangling link: replaced
            except OSError as exc:
                raise InputError(f"output {shown} is a symbolic link that cannot be followed: "
                                 f"{exc.strerror or exc}") from None
        stream = _open_file_link(path)
        if stream is not None:
            raise InputError(f"output {shown} leads to a process's open file ({show(stream)}): a "
                             "stream, not a file to replace; write to a regular file or a new path")
        if target is not None:
            for test, kind in _KINDS:
                if test(target.st_mode):
                    link = "a symbolic link to " if target is not here else ""
                    raise InputError(f"output {shown} is {link}{kind}: it should be a regular file "
                                     "or a new path")
        if (here.st_dev, here.st_ino) in taken:
            source = taken[(here.st_dev, here.st_ino)]
            raise InputError(f"output {shown} is the input file {show(str(source))}: writing it "
                             "would replace it; choose another output path")


# Linux proc(5): /proc/[pid]/fd/N are links to a process's open files (/dev/stdout is a link to
# /proc/self/fd/1, /dev/fd to /proc/self/fd).
_PROC = "/proc"
_MAX_LINKS = 40  # Linux path_resolution(7): at most 40 symbolic links in one resolution


def _open_file_link(path) -> str | None:
    """The ``/proc`` path ``path`` resolves through, if it does (None otherwise)."""
    current = os.path.abspath(path)
    for _ in range(_MAX_LINKS):
        parent = os.path.realpath(os.path.dirname(current))
        current = os.path.join(parent, os.path.basename(current))
        if current == _PROC or current.startswith(_PROC + "/"):
            return current
        if not os.path.islink(current):
            return None
        try:
            current = os.path.join(parent, os.readlink(current))
        except OSError:
            return None
    return None  # a loop: the lstat/stat checks report it


def write_files(contents: dict, inputs=()) -> None:
    """Write ``{path: text or bytes}`` atomically, as one group.

    Parameters
    ----------
    contents : dict
        ``{path: text or bytes}``.
    inputs : iterable of path
        The files the output was made from: refused as outputs (:func:`check_outputs`).

    Raises
    ------
    InputError
        An output that must not be replaced (:func:`check_outputs`), before anything is written.
    OSError
        From creating, writing or renaming; the files already at those paths are then intact
        and no temporary file is left behind.
    """
    check_outputs(contents, inputs)
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
