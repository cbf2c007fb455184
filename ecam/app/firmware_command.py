"""`ecam firmware --emit DIR`: the C reference runtime (``ecam_table.c``, ``ecam_table.h``), the
table switch at a period boundary (``ecam_table_pair.c``, ``ecam_table_pair.h``) and the table
format they implement (``FORMAT.md``), written from the installed package, so a firmware project
can take the runtime that matches its ecam (every generated header points to them)."""

from __future__ import annotations

from pathlib import Path

from ecam.atomic_files import write_files
from ecam.errors import InputError

#: The runtime's files, shipped as package data (links to firmware_tables/ in a checkout).
RUNTIME_DIR = Path(__file__).resolve().parents[1] / "c_runtime"
RUNTIME_FILES = ("ecam_table.h", "ecam_table.c", "ecam_table_pair.h", "ecam_table_pair.c", "FORMAT.md")


def runtime_files() -> dict[str, bytes]:
    """The runtime's files by name, as the package holds them."""
    out = {}
    for name in RUNTIME_FILES:
        try:
            out[name] = (RUNTIME_DIR / name).read_bytes()
        except OSError as exc:  # a broken install: say which file is missing
            raise InputError(f"the C runtime's {name} is missing from the installed package "
                             f"({RUNTIME_DIR}): {exc.strerror or exc}") from None
    return out


def cmd_firmware(args) -> int:
    """Write the runtime's files into ``args.emit`` (created if missing); print what it wrote."""
    target = Path(args.emit)
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--emit: {str(target)!r} cannot be created: {exc.strerror or exc}") from None
    files = runtime_files()
    paths = {target / name: content for name, content in files.items()}
    try:
        write_files(paths)
    except OSError as exc:
        raise InputError(f"--emit: {str(target)!r} cannot be written: {exc.strerror or exc}") from None
    for path in paths:
        print(f"wrote {path}")
    print("build: cc -std=c99 -c ecam_table.c; load a blob with ecam_table_init (see FORMAT.md); "
          "ecam_table_pair.c (optional) switches tables at a period boundary")
    return 0
