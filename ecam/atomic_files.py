"""Writing output files so that a crash, a full disk or a kill never leaves a half-written one.

Used by the command line and the firmware generator (the library itself returns text and bytes
and writes nothing). Each file is written to a temporary file in its own directory, flushed to
disk, and renamed over the target; a group of files (a table's .h, .bin, .json ...) is renamed
only once every member has been written, so they appear together or not at all. An output that
is a symbolic link to a regular file is replaced by the new file, never followed: its target is
left untouched.

A group is switched in one step for its readers by a manifest written last
(:func:`write_group`): before the first rename the old manifest goes, after the last the new one
names every member with its size and SHA-256, so a reader that checks it (:func:`check_group`)
never takes a new header beside an old blob, as a kill between two renames left them (issue 28,
item 6). Temporaries a killed writer left behind (``.NAME.*.tmp`` beside an output, older than
:data:`STALE_TEMPORARY_S`) are removed by the next write of that output.

What an output must never replace is refused first, in one line (:func:`check_outputs`): a
device node, FIFO, socket or directory (``-o /dev/null`` as root made the device a regular
file), a symbolic link to one of those or to a process's open file (``--junit /dev/stdout``,
a link to ``/proc/self/fd/1``: a stream, though it may name a regular file while the output is
redirected), and the command's own input files (``ecam export cam.toml -o cam.toml``), which
the rename would silently replace.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import tempfile
import time
from pathlib import Path

from .errors import InputError
from .validate import show, show_path

__all__ = ["write_files", "write_group", "check_group", "check_outputs", "STALE_TEMPORARY_S"]

#: A temporary of an output older than this [s] is a killed writer's, removed by the next write
#: (a writer running now renames its own within a second or so).
STALE_TEMPORARY_S = 600.0
#: The manifest's format.
GROUP_FORMAT = "ecam output group 1"
#: Largest manifest check_group reads [bytes].
_MAX_MANIFEST_BYTES = 1 << 20

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
        shown = show_path(path)
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
            raise InputError(f"output {shown} is the input file {show_path(source)}: writing it "
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
    _remove_stale_temporaries(contents)
    staged = _stage(contents)
    _commit(staged)


def write_group(contents: dict, manifest, inputs=()) -> Path:
    """Write ``{path: text or bytes}`` as one group with its manifest, written last.

    Parameters
    ----------
    contents : dict
        The members, all in one directory.
    manifest : path
        The manifest file (JSON: every member's name, size and SHA-256, sorted; no date).
    inputs : iterable of path
        Files the group was made from (refused as outputs).

    Returns
    -------
    Path
        The manifest.

    Raises
    ------
    InputError, OSError
        As :func:`write_files`; until the new manifest is in place no manifest names the
        members, so a reader that checks it refuses a group half switched.
    """
    manifest = Path(manifest)
    check_outputs([*contents, manifest], inputs)
    _remove_stale_temporaries([*contents, manifest])
    data = {Path(path): _bytes(content) for path, content in contents.items()}
    listing = {"format": GROUP_FORMAT, "files": [
        {"name": path.name, "bytes": len(blob), "sha256": hashlib.sha256(blob).hexdigest()}
        for path, blob in sorted(data.items(), key=lambda item: item[0].name)]}
    staged = _stage(data)
    try:
        manifest.unlink(missing_ok=True)  # from here until the new one, the group is in flux
    except BaseException:
        _discard(staged)
        raise
    _commit(staged)
    _commit(_stage({manifest: json.dumps(listing, indent=1, sort_keys=True) + "\n"}))
    return manifest


def check_group(manifest) -> list[Path]:
    """The members of the group a manifest names, each checked against it.

    Raises
    ------
    InputError
        A missing or malformed manifest, or a member missing or not the one the manifest names
        (a group half switched by a killed writer, or edited since).
    """
    manifest = Path(manifest)
    shown = show_path(manifest)
    try:
        with open(manifest, "rb") as handle:
            listing = json.loads(handle.read(_MAX_MANIFEST_BYTES + 1)[:_MAX_MANIFEST_BYTES])
        files = listing["files"] if listing.get("format") == GROUP_FORMAT else None
        if not isinstance(files, list):
            raise ValueError("no file list")
        members = [(manifest.parent / entry["name"], entry["bytes"], entry["sha256"]) for entry in files]
    except FileNotFoundError:
        raise InputError(f"output group {shown}: no manifest (a write did not finish)") from None
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"output group {shown} cannot be read: {exc}") from None
    for path, size, digest in members:
        try:
            blob = path.read_bytes() if path.stat().st_size == size else None
        except OSError:
            blob = None
        if blob is None or hashlib.sha256(blob).hexdigest() != digest:
            raise InputError(f"output group {shown}: {show(path.name)} is not the file the manifest "
                             "names (a write did not finish, or it was changed)")
    return [path for path, _, _ in members]


def _bytes(content) -> bytes:
    return content.encode("utf-8") if isinstance(content, str) else bytes(content)


def _remove_stale_temporaries(paths) -> None:
    """Remove what a killed writer of these outputs left (``.NAME.*.tmp``, older than
    :data:`STALE_TEMPORARY_S`)."""
    now = time.time()
    for path in paths:
        path = Path(path)
        try:
            leftovers = list(path.parent.glob(f".{_glob_escape(path.name)}.*.tmp"))
        except OSError:
            continue
        for leftover in leftovers:
            try:
                if now - os.lstat(leftover).st_mtime > STALE_TEMPORARY_S:
                    os.unlink(leftover)
            except OSError:
                pass  # gone already, or not ours to remove


def _glob_escape(name: str) -> str:
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)


def _stage(contents: dict) -> list[tuple[str, Path]]:
    """Each member written to a temporary beside it and flushed: [(temporary, path)]."""
    staged: list[tuple[str, Path]] = []
    try:
        for path, content in contents.items():
            path = Path(path)
            data = _bytes(content)
            fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
            staged.append((temporary, path))
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
            os.chmod(temporary, 0o644)  # mkstemp makes 0600; outputs are ordinary files
    except BaseException:
        _discard(staged)
        raise
    return staged


def _commit(staged: list[tuple[str, Path]]) -> None:
    """Rename the temporaries over their outputs; on a failure, remove those not renamed."""
    try:
        for temporary, path in staged:
            os.replace(temporary, path)
    except BaseException:
        _discard(staged)
        raise


def _discard(staged: list[tuple[str, Path]]) -> None:
    for temporary, _ in staged:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
