"""The C runtime on other targets: toolchains, builds and runners for the cross-target tests and the
bench's Cortex-M4 figures.

A target is a compiler, its flags and a way to run what it builds: Cortex-M4 (arm-none-eabi-gcc
with newlib's semihosting, QEMU machine mps2-an386), PPC32 big-endian, armhf and i386 Linux
binaries (static, under qemu-user or natively). Every program is firmware_tables/ecam_target.c
plus the runtime: files in, files out, so the host compares the results bit for bit.
:func:`missing` says which tool (and which Debian package) a target lacks; nothing here raises
for a missing tool.
"""

from __future__ import annotations

import os
import platform
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from ..firmware import FIRMWARE_DIR

# The driver (ecam_target.c and its file reader, semihosted on the M4) and what it measures.
RUNTIME_SOURCES = ("ecam_target.c", "ecam_host_io.c", "ecam_table.c", "ecam_minimal.c")
M4_FLAGS = ("-mcpu=cortex-m4", "-mthumb", "-std=c99")
M4_MACHINE = "mps2-an386"


@dataclass(frozen=True)
class Target:
    """One place the runtime must run bit for bit."""

    name: str
    compiler: str
    flags: tuple
    runner: tuple  # command prefix; () = run natively
    packages: str  # Debian packages that provide the tools
    tools: tuple = field(default=())  # every executable the target needs

    @property
    def semihosted(self) -> bool:
        return self.runner[:1] == ("qemu-system-arm",)


def _i386() -> Target:
    native = platform.machine() in ("x86_64", "AMD64", "i386", "i686")
    runner = () if native else ("qemu-i386",)
    return Target("i386", "i686-linux-gnu-gcc", ("-std=c99", "-static"), runner,
                  "gcc-i686-linux-gnu" + ("" if native else " qemu-user"),
                  ("i686-linux-gnu-gcc", *runner))  # fmt: skip


TARGETS = {
    "cortex-m4": Target("cortex-m4", "arm-none-eabi-gcc", (*M4_FLAGS, "--specs=rdimon.specs"),
                        ("qemu-system-arm",), "gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm",
                        ("arm-none-eabi-gcc", "qemu-system-arm")),
    "ppc32": Target("ppc32", "powerpc-linux-gnu-gcc", ("-std=c99", "-static"), ("qemu-ppc",),
                    "gcc-powerpc-linux-gnu qemu-user", ("powerpc-linux-gnu-gcc", "qemu-ppc")),
    "i386": _i386(),
    "armhf": Target("armhf", "arm-linux-gnueabihf-gcc", ("-std=c99", "-static"), ("qemu-arm",),
                    "gcc-arm-linux-gnueabihf qemu-user", ("arm-linux-gnueabihf-gcc", "qemu-arm")),
}  # fmt: skip


def missing(target: Target) -> str:
    """'' when every tool of the target is installed, else one line naming what is missing."""
    absent = [tool for tool in target.tools if shutil.which(tool) is None]
    if not absent and target.semihosted and not _newlib_present():
        absent = ["newlib's rdimon.specs"]
    if not absent:
        return ""
    return f"{target.name}: {', '.join(absent)} not found (Debian: apt-get install {target.packages})"


def _newlib_present() -> bool:
    proc = subprocess.run(["arm-none-eabi-gcc", "-print-file-name=rdimon.specs"], capture_output=True, text=True)
    return proc.returncode == 0 and os.path.isabs(proc.stdout.strip()) and Path(proc.stdout.strip()).is_file()


def build(target: Target, out: Path, flags: list | tuple = (), sources=RUNTIME_SOURCES) -> Path:
    """Compile ecam_target.c with the runtime for the target; raises RuntimeError with the
    compiler's first error line."""
    extra = []
    if target.semihosted:
        extra = ["-T", str(FIRMWARE_DIR / "targets" / "cortex_m4.ld"),
                 str(FIRMWARE_DIR / "targets" / "cortex_m4_startup.c")]  # fmt: skip
    cmd = [target.compiler, *target.flags, *flags, "-I", str(FIRMWARE_DIR), *extra,
           *(str(FIRMWARE_DIR / s) for s in sources), "-o", str(out)]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        first = (proc.stderr.strip().splitlines() or ["(no message)"])[0]
        raise RuntimeError(f"{target.name} build failed: {first}")
    return out


def qemu_m4_command(executable: Path, args: list, trace: Path | None = None, ranges=()) -> list:
    """qemu-system-arm on mps2-an386 with semihosting (argv, files, exit status); with `trace`,
    one log line per executed instruction (one instruction per translation block, no chaining),
    only for addresses in `ranges` ((start, size) pairs) when given."""
    cmd = ["qemu-system-arm", "-M", M4_MACHINE, "-nographic", "-monitor", "none", "-serial", "none"]
    if trace is not None:
        cmd += [*_one_instruction_per_block(), "-d", "exec,nochain", "-D", str(trace)]
        if ranges:
            cmd += ["-dfilter", ",".join(f"0x{start:x}+0x{size:x}" for start, size in ranges)]
    semihosting = ",".join(["enable=on", "target=native", "arg=ecam_target", *(f"arg={a}" for a in args)])
    return [*cmd, "-semihosting-config", semihosting, "-kernel", str(executable)]


def _one_instruction_per_block() -> list:
    version = subprocess.run(["qemu-system-arm", "--version"], capture_output=True, text=True).stdout
    match = re.search(r"version (\d+)\.(\d+)", version)
    if match and (int(match.group(1)), int(match.group(2))) >= (8, 1):
        return ["-accel", "tcg,one-insn-per-tb=on"]  # what -singlestep became in QEMU 8.1
    return ["-singlestep"]


def run(target: Target, executable: Path, args: list, cwd: Path, timeout: float = 600,
        trace: Path | None = None, ranges=()) -> subprocess.CompletedProcess:
    """Run ecam_target on the target with `args` (paths relative to cwd: QEMU's semihosting
    argument list is comma-separated, so paths must not contain commas)."""
    if any("," in str(a) for a in args):
        raise ValueError(f"{target.name}: an argument contains a comma: {args}")
    if target.semihosted:
        cmd = qemu_m4_command(executable, args, trace, ranges)
    else:
        cmd = [*target.runner, str(executable), *map(str, args)]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
