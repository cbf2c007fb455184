"""Instructions per lookup, counted exactly, and the Cortex-M4 footprint.

Counts, not times: the same binary and inputs give the same numbers on any machine, loaded or not.

- x86-64 (here): ``valgrind --tool=callgrind --toggle-collect=FUNCTION``, i.e. every instruction
  executed inside one call of FUNCTION and what it calls, summed over the queries;
- Cortex-M4: QEMU ``mps2-an386`` with one instruction per translation block and an ``exec`` log,
  counting the instructions whose address lies in the runtime's (or the minimal lookup's)
  functions, from the first call on; the number of calls is the number of entries.

What is compared (issue 11): ``runtime`` is one call of ``ecam_table_position`` (entry, kernel,
wrap); ``minimal`` is one call of ``ecam_minimal_<degree>`` from firmware_tables/ecam_minimal.c,
compiled in the same run with this table's format as compile-time constants, aligned native
int32 arrays and the master already inside [0, M) -- what a hand-written lookup of this one table
costs. ``inside``: masters uniform over [0, M); ``wide``: uniform over int64 (each one wraps).
The runtime's checksum on the inside queries must equal the minimal lookup's (the same bits).
The contract: runtime / minimal <= 2 inside and <= 3 wide, on both targets at -O2.

Cortex-M4 footprint: flash (text + rodata) and RAM (data + bss) of ecam_table.o from
arm-none-eabi-size, the largest frame of every lookup function from -fstack-usage, the measured
stack of one call (stack painting under QEMU) and sizeof(ecam_table), at -Os and -O2.

Bench rows (kind ``"note"``, so every consumer of the existing kinds keeps working):

- topic ``"instructions"``: ``target`` ("x86-64" or "cortex-m4"), ``compiler``, ``interp``,
  ``points``, ``step_counts``, ``queries``, ``instructions_runtime_inside``,
  ``instructions_runtime_wide``, ``instructions_minimal``, ``ratio_inside``, ``ratio_wide``,
  ``limit_inside`` (2), ``limit_wide`` (3), ``checksums_match``, ``met``, ``text``; or only
  ``target`` and ``text`` saying what was not measured and why (a missing tool is named);
- topic ``"cortex-m4"``: ``opt``, ``flash_bytes``, ``ram_bytes``, ``text_bytes``/``data_bytes``/``bss_bytes``,
  ``largest_frame``, ``frames``, ``stack_per_call`` (per degree: position, slope, lookup, init),
  ``stack_per_call_max``, ``table_bytes``, ``pair_bytes``, ``text``; or a note naming the
  missing tool.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ecam.compile import compile_table

from .cross import TARGETS, build, missing, run
from .plan import FIRMWARE_DIR, MASTER_COUNTS, SEED_CAM, STROKE_COUNTS, bench_profile

DEGREES = {1: "linear", 3: "cubic", 5: "quintic"}
LIMITS = {"inside": 2.0, "wide": 3.0}
HOST_FLAGS = ("-O2", "-std=c99")
M4_OPTS = ("-Os", "-O2")
_SEED = 20261123


@dataclass(frozen=True)
class Measured:
    """Mean instructions per call (None where not measured) and how."""

    runtime_inside: float
    runtime_wide: float
    minimal: float
    checksums_match: bool

    @property
    def ratio_inside(self) -> float:
        return self.runtime_inside / self.minimal

    @property
    def ratio_wide(self) -> float:
        return self.runtime_wide / self.minimal


def minimal_defines(fmt) -> list[str]:
    """The table's format as ecam_minimal.c's compile-time constants."""
    return [f"-DECAM_MIN_STEP={fmt.step_counts}u", f"-DECAM_MIN_TAU_BITS={fmt.tau_bits}",
            f"-DECAM_MIN_TAU_RECIP={fmt.tau_recip}u", f"-DECAM_MIN_WORK_BITS={fmt.work_bits}",
            f"-DECAM_MIN_POSITION_BITS={fmt.position_bits}", f"-DECAM_MIN_SLOPE_BITS={fmt.slope_bits}",
            f"-DECAM_MIN_CURVATURE_BITS={fmt.curvature_bits}"]  # fmt: skip


def write_queries(directory: Path, master_counts: int, count: int) -> tuple[str, str]:
    """inside.i64 (uniform over [0, M)) and wide.i64 (uniform over int64), raw little-endian."""
    rng = np.random.default_rng(_SEED)
    rng.integers(0, master_counts, count, dtype=np.int64).astype("<i8").tofile(directory / "inside.i64")
    wide = rng.integers(-(2**63), 2**63 - 1, count, dtype=np.int64, endpoint=True)
    wide.astype("<i8").tofile(directory / "wide.i64")
    return "inside.i64", "wide.i64"


# --- x86-64: callgrind ---------------------------------------------------------------------------


def host_compiler() -> str | None:
    return next((shutil.which(c) for c in (os.environ.get("CC", "cc"), "cc", "gcc", "clang")
                 if c and shutil.which(c)), None)  # fmt: skip


def host_note() -> str:
    """'' when x86 counts can be taken, else why not."""
    if host_compiler() is None:
        return "no C compiler (cc, gcc, clang) on PATH"
    if shutil.which("valgrind") is None:
        return "valgrind not found (Debian: apt-get install valgrind)"
    return ""


def _callgrind(exe: Path, args: list, function: str, cwd: Path) -> tuple[int, str]:
    """(instructions collected inside `function`, the program's stdout)."""
    out = cwd / "callgrind.out"
    proc = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                           f"--toggle-collect={function}", str(exe), *args],
                          cwd=cwd, capture_output=True, text=True, timeout=600)  # fmt: skip
    if proc.returncode != 0:
        raise RuntimeError(f"callgrind {function}: {(proc.stderr.strip().splitlines() or ['?'])[-1]}")
    text = out.read_text()
    match = re.search(r"^(?:summary|totals):\s+(\d+)", text, re.M)
    if match is None:
        raise RuntimeError("callgrind wrote no totals")
    return int(match.group(1)), proc.stdout


def host_counts(directory: Path, blob: bytes, fmt, count: int) -> Measured:
    """x86-64 counts of one table (cc -O2), per call."""
    cc = host_compiler()
    exe = directory / "ecam_count_host"
    cmd = [cc, *HOST_FLAGS, *minimal_defines(fmt), "-I", str(FIRMWARE_DIR),
           *(str(FIRMWARE_DIR / s) for s in ("ecam_target.c", "ecam_table.c", "ecam_minimal.c")), "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError(f"host build failed: {(proc.stderr.strip().splitlines() or ['?'])[0]}")
    (directory / "table.bin").write_bytes(blob)
    inside, wide = write_queries(directory, fmt.master_counts, count)
    name = DEGREES[fmt.degree]
    runtime_in, out_in = _callgrind(exe, ["count", "table.bin", inside, "runtime"], "ecam_table_position", directory)
    runtime_wide, _ = _callgrind(exe, ["count", "table.bin", wide, "runtime"], "ecam_table_position", directory)
    minimal, out_min = _callgrind(exe, ["count", "table.bin", inside, "minimal"], f"ecam_minimal_{name}", directory)
    return Measured(runtime_in / count, runtime_wide / count, minimal / count, out_in.split() == out_min.split())


# --- Cortex-M4: QEMU instruction trace -----------------------------------------------------------


def m4_note() -> str:
    """'' when Cortex-M4 figures can be taken, else which tool is missing."""
    why = missing(TARGETS["cortex-m4"])
    for tool, package in (("arm-none-eabi-size", "binutils-arm-none-eabi"), ("arm-none-eabi-nm", "binutils-arm-none-eabi")):
        if not why and shutil.which(tool) is None:
            why = f"cortex-m4: {tool} not found (Debian: apt-get install {package})"
    return why


def _objects(directory: Path, opt: str, defines: list) -> dict:
    """ecam_table.o and ecam_minimal.o for the M4 at `opt` (their symbols delimit the counting)."""
    out = {}
    for source in ("ecam_table.c", "ecam_minimal.c"):
        obj = directory / f"m4{opt}_{source[:-2]}.o"
        cmd = ["arm-none-eabi-gcc", "-mcpu=cortex-m4", "-mthumb", "-std=c99", opt, *defines, "-fstack-usage",
               "-I", str(FIRMWARE_DIR), "-c", str(FIRMWARE_DIR / source), "-o", str(obj)]  # fmt: skip
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=directory, timeout=300)
        if proc.returncode != 0:
            raise RuntimeError(f"cortex-m4 {source}: {(proc.stderr.strip().splitlines() or ['?'])[0]}")
        out[source[:-2]] = obj
    return out


def _functions(nm_target: Path) -> dict:
    """name -> (start, size) of every function of an object or ELF file."""
    proc = subprocess.run(["arm-none-eabi-nm", "-S", str(nm_target)], capture_output=True, text=True)
    out = {}
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "tT":
            out[parts[3]] = (int(parts[0], 16) & ~1, int(parts[1], 16))
    return out


def counted_ranges(elf: Path, objects: list) -> list:
    """(start, size) of the functions defined in `objects` (and libgcc's __aeabi helpers) in the ELF."""
    names = set()
    for obj in objects:
        names.update(_functions(obj))
    return sorted((start, size) for name, (start, size) in _functions(elf).items()
                  if size and (name in names or name.startswith("__aeabi_")))  # fmt: skip


def trace_count(elf: Path, trace: Path, entry: str, objects: list) -> tuple[int, int]:
    """(calls of `entry`, instructions executed in the functions of `objects` from the first call
    on): the QEMU exec log has one line per instruction ("[cs_base/pc/flags/cflags]")."""
    ranges = [(start, start + size) for start, size in counted_ranges(elf, objects)]
    starts = np.array([a for a, _ in ranges], dtype=np.int64)
    ends = np.array([b for _, b in ranges], dtype=np.int64)
    entry_address = _functions(elf)[entry][0]
    pattern = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/")
    pcs = np.array([int(m.group(1), 16) for m in map(pattern.search, trace.read_text().splitlines()) if m],
                   dtype=np.int64)  # fmt: skip
    first = np.flatnonzero(pcs == entry_address)
    if not first.size:
        return 0, 0
    pcs = pcs[first[0]:]
    slot = np.searchsorted(starts, pcs, side="right") - 1
    inside = (slot >= 0) & (pcs < ends[np.clip(slot, 0, None)])
    return int(np.count_nonzero(pcs == entry_address)), int(np.count_nonzero(inside))


def m4_counts(directory: Path, blob: bytes, fmt, count: int, opt: str = "-O2") -> Measured:
    """Cortex-M4 counts of one table, per call."""
    target = TARGETS["cortex-m4"]
    defines = minimal_defines(fmt)
    elf = build(target, directory / f"ecam_count_m4{opt}.elf", [opt, *defines])
    objects = _objects(directory, opt, defines)
    (directory / "table.bin").write_bytes(blob)
    inside, wide = write_queries(directory, fmt.master_counts, count)
    name = DEGREES[fmt.degree]
    results = {}
    for key, queries, what, entry, obj in (
        ("runtime_inside", inside, "runtime", "ecam_table_position", objects["ecam_table"]),
        ("runtime_wide", wide, "runtime", "ecam_table_position", objects["ecam_table"]),
        ("minimal", inside, "minimal", f"ecam_minimal_{name}", objects["ecam_minimal"]),
    ):
        trace = directory / "trace.log"
        proc = run(target, elf, ["count", "table.bin", queries, what], directory, trace=trace,
                   ranges=counted_ranges(elf, [obj]))
        if proc.returncode != 0:
            raise RuntimeError(f"cortex-m4 count {what}: exit {proc.returncode} {proc.stdout.strip()} {proc.stderr.strip()}")
        calls, instructions = trace_count(elf, trace, entry, [obj])
        if calls != count:
            raise RuntimeError(f"cortex-m4 trace saw {calls} calls of {entry}, expected {count}")
        results[key] = (instructions / calls, proc.stdout.split())
        trace.unlink()
    match = results["runtime_inside"][1] == results["minimal"][1]
    return Measured(results["runtime_inside"][0], results["runtime_wide"][0], results["minimal"][0], match)


def _stack_usage(su: Path) -> dict:
    """function -> frame bytes, from a -fstack-usage file."""
    out = {}
    for line in su.read_text().splitlines():
        parts = line.split("\t")
        if len(parts) >= 2:
            out[parts[0].rsplit(":", 1)[-1]] = int(parts[1])
    return out


def m4_footprint(directory: Path, blobs: dict) -> list[dict]:
    """Flash, RAM and stack of the runtime on the Cortex-M4 at -Os and -O2 (one dict each).
    `blobs`: degree -> blob, for the measured (painted) stack of each API call."""
    target = TARGETS["cortex-m4"]
    rng = np.random.default_rng(_SEED + 1)
    out = []
    for opt in M4_OPTS:
        objects = _objects(directory, opt, [])
        size = subprocess.run(["arm-none-eabi-size", str(objects["ecam_table"])], capture_output=True, text=True)
        text, data, bss = (int(v) for v in size.stdout.splitlines()[1].split()[:3])
        frames = _stack_usage(objects["ecam_table"].with_suffix(".su"))
        kernel_frames = {name: frames[name] for name in frames if name != "ecam_slope_ok" and name.startswith(
            ("ecam_position_", "ecam_slope_", "ecam_table_position", "ecam_table_slope", "ecam_table_lookup",
             "ecam_general", "ecam_coefficient", "ecam_quintic", "ecam_cubic", "ecam_linear"))}  # fmt: skip
        elf = build(target, directory / f"ecam_stack_m4{opt}.elf", [opt])
        painted = {}
        sizes = {}
        for degree, blob in sorted(blobs.items()):
            (directory / "stack.bin").write_bytes(blob)
            master_counts = int.from_bytes(blob[20:24], "little")
            queries = np.concatenate([rng.integers(0, master_counts, 64, dtype=np.int64),
                                      rng.integers(-(2**63), 2**63 - 1, 64, dtype=np.int64)])  # fmt: skip
            queries.astype("<i8").tofile(directory / "stack.i64")
            proc = run(target, elf, ["stack", "stack.bin", "stack.i64"], directory)
            if proc.returncode != 0:
                raise RuntimeError(f"cortex-m4 stack: exit {proc.returncode} {proc.stdout.strip()}")
            words = proc.stdout.split()
            values = dict(zip(words[::2], (int(w) for w in words[1::2])))
            painted[DEGREES[degree]] = {k: values[k] for k in ("position", "slope", "lookup", "init")}
            sizes = {k: values[k] for k in ("table_bytes", "pair_bytes")}
        out.append({"opt": opt, "flash_bytes": text + data, "ram_bytes": data + bss, "text_bytes": text,
                    "data_bytes": data, "bss_bytes": bss, "largest_frame": max(kernel_frames.values()), "frames": kernel_frames,
                    "stack_per_call": painted, **sizes})  # fmt: skip
    return out


# --- bench rows ----------------------------------------------------------------------------------


def bench_tables(quick: bool) -> list:
    """The measured tables: the seed cam at the bench scale, each kind at 145 points (h = 8192, a
    power of two); the full run adds 97 points (h = 12288, not a power of two)."""
    profile = bench_profile(SEED_CAM)
    low, high = profile.slave_range
    scale = STROKE_COUNTS / (high - low)
    out = []
    for points in (145,) if quick else (145, 97):
        for kind in ("linear", "cubic", "quintic"):
            out.append(compile_table(profile, interp=kind, points=points, master_counts=MASTER_COUNTS,
                                     slave_counts_per_unit=scale))  # fmt: skip
    return out


def _describe(table) -> str:
    f = table.format
    return f"{SEED_CAM} {DEGREES[f.degree]}, {f.points} points (h = {f.step_counts})"


def _row(target: str, compiler: str, table, m: Measured, count: int) -> dict:
    met = m.ratio_inside <= LIMITS["inside"] and m.ratio_wide <= LIMITS["wide"] and m.checksums_match
    text = (f"instructions per lookup, {target} ({compiler}), {_describe(table)}: runtime {m.runtime_inside:.1f} "
            f"inside the period / {m.runtime_wide:.1f} any int64, minimal {m.minimal:.1f}: "
            f"{m.ratio_inside:.2f}x / {m.ratio_wide:.2f}x (limits {LIMITS['inside']:g}x / {LIMITS['wide']:g}x): "
            f"{'met' if met else 'MISSED'}{'' if m.checksums_match else '; CHECKSUMS DIFFER'}")
    return {"kind": "note", "topic": "instructions", "target": target, "compiler": compiler,
            "interp": DEGREES[table.format.degree], "points": table.points, "step_counts": table.format.step_counts,
            "queries": count, "instructions_runtime_inside": m.runtime_inside,
            "instructions_runtime_wide": m.runtime_wide, "instructions_minimal": m.minimal,
            "ratio_inside": m.ratio_inside, "ratio_wide": m.ratio_wide, "limit_inside": LIMITS["inside"],
            "limit_wide": LIMITS["wide"], "checksums_match": m.checksums_match, "met": met, "text": text}  # fmt: skip


def instruction_rows(directory: Path, quick: bool) -> list[dict]:
    """The bench's instruction and Cortex-M4 rows (kind "note", topics "instructions" and
    "cortex-m4"); a note saying which tool is missing where a target cannot be measured."""
    count = 200 if quick else 1000
    rows = []
    tables = bench_tables(quick)
    why = host_note()
    if why:
        rows.append({"kind": "note", "topic": "instructions", "target": "x86-64",
                     "text": f"instructions per lookup on x86-64 not measured: {why}"})
    else:
        for table in tables:
            work = directory / f"host_{table.format.degree}_{table.points}"
            work.mkdir()
            try:
                rows.append(_row("x86-64", "cc -O2, callgrind", table, host_counts(work, table.to_bytes(), table.format, count), count))
            except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
                rows.append({"kind": "note", "topic": "instructions", "target": "x86-64",
                             "text": f"instructions per lookup on x86-64, {_describe(table)}: not measured: {exc}"})
    why = m4_note()
    if why:
        rows.append({"kind": "note", "topic": "cortex-m4", "target": "cortex-m4",
                     "text": f"Cortex-M4 figures (size, stack, instructions) not measured: {why}"})
        return rows
    for table in tables:
        work = directory / f"m4_{table.format.degree}_{table.points}"
        work.mkdir()
        try:
            rows.append(_row("cortex-m4", f"arm-none-eabi-gcc -O2, QEMU {TARGETS['cortex-m4'].name} trace", table,
                             m4_counts(work, table.to_bytes(), table.format, count), count))
        except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
            rows.append({"kind": "note", "topic": "instructions", "target": "cortex-m4",
                         "text": f"instructions per lookup on Cortex-M4, {_describe(table)}: not measured: {exc}"})
    work = directory / "m4_footprint"
    work.mkdir()
    try:
        blobs = {t.format.degree: t.to_bytes() for t in tables if t.points == 145}
        for f in m4_footprint(work, blobs):
            stack = f["stack_per_call"]
            worst = {api: max(stack[d][api] for d in stack) for api in ("position", "slope", "lookup")}
            text = (f"Cortex-M4 {f['opt']}: ecam_table.o flash {f['flash_bytes']} B, RAM {f['ram_bytes']} B (static); "
                    f"sizeof(ecam_table) {f['table_bytes']} B, ecam_table_pair {f['pair_bytes']} B; stack per call "
                    f"(measured) position {worst['position']} B, slope {worst['slope']} B, lookup {worst['lookup']} B; "
                    f"largest frame {f['largest_frame']} B (-fstack-usage)")
            rows.append({"kind": "note", "topic": "cortex-m4", "target": "cortex-m4", **f,
                         "stack_per_call_max": worst, "text": text})
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        rows.append({"kind": "note", "topic": "cortex-m4", "target": "cortex-m4",
                     "text": f"Cortex-M4 footprint not measured: {exc}"})
    return rows
