"""The C runtime under the bench: ecam_bench.c (with ecam_host_io.c) + ecam_table.c compiled once, run on
query files."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

from ..firmware import FIRMWARE_DIR


class CRuntime:
    """ecam_bench.c, ecam_host_io.c and ecam_table.c compiled once into a temporary directory."""

    def __init__(self, directory: Path):
        self.directory = directory
        self.executable = None
        self.note = ""
        self.command = ""
        sources = [FIRMWARE_DIR / "ecam_bench.c", FIRMWARE_DIR / "ecam_host_io.c", FIRMWARE_DIR / "ecam_table.c"]
        headers = [FIRMWARE_DIR / "ecam_table.h", FIRMWARE_DIR / "ecam_host_io.h"]
        missing = [str(s) for s in sources + headers if not s.is_file()]
        compiler = next((shutil.which(c) for c in (os.environ.get("CC", "cc"), "cc", "gcc", "clang")
                         if c and shutil.which(c)), None)
        if missing:
            self.note = f"C runtime skipped: {', '.join(missing)} not found (run from a source checkout)"
            return
        if compiler is None:
            self.note = "C runtime skipped: no C compiler (cc, gcc, clang) on PATH"
            return
        exe = directory / "ecam_bench"
        cmd = [compiler, "-O2", "-std=c99", "-I", str(FIRMWARE_DIR), "-o", str(exe), *map(str, sources)]
        self.command = f"{Path(compiler).name} -O2 -std=c99 ecam_bench.c ecam_host_io.c ecam_table.c"
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.TimeoutExpired) as exc:
            self.note = f"C runtime skipped: {self.command} failed: {exc}"
            return
        if proc.returncode != 0:
            first = (proc.stderr.strip().splitlines() or ["(no message)"])[0]
            self.note = f"C runtime skipped: {self.command} failed: {first}"
            return
        self.executable = exe

    def run(self, blob: bytes, repeats: int, query_files) -> list:
        """[(ns_per_lookup, checksum)] per query file; raises RuntimeError with the reason."""
        blob_path = self.directory / "table.bin"
        blob_path.write_bytes(blob)
        try:
            proc = subprocess.run([str(self.executable), str(blob_path), str(repeats), *map(str, query_files)],
                                  capture_output=True, text=True, timeout=600)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise RuntimeError(f"ecam_bench did not run: {exc}") from None
        if proc.returncode != 0:
            why = (proc.stdout.strip() or proc.stderr.strip() or f"exit status {proc.returncode}").splitlines()[0]
            raise RuntimeError(f"ecam_bench: {why}")
        out = []
        for line in proc.stdout.split("\n"):
            if line.strip():
                ns, total = line.split()
                out.append((float(ns), int(total)))
        if len(out) != len(query_files):
            raise RuntimeError(f"ecam_bench printed {len(out)} lines for {len(query_files)} query files")
        return out


# --- one table ----------------------------------------------------------------------------------
