"""Instructions per lookup, counted exactly, and the Cortex-M4 footprint.

Counts, not times: the same binary and inputs give the same numbers on any machine, loaded or not.

- x86-64 (here): ``valgrind --tool=callgrind --toggle-collect=FUNCTION``, i.e. every instruction
  executed inside one call of FUNCTION and what it calls, summed over the queries;
- Cortex-M4: QEMU ``mps2-an386`` with one instruction per translation block and an ``exec`` log
  filtered to the functions a lookup can run and the driver loop that calls it
  (:func:`count_ranges`): each call counts every instruction from its entry until control is
  back in the driver, the same inclusive count (tests/test_cross_targets.py checks it against an
  unfiltered log, call by call). The loader's functions are left out of the log: a large
  table's overflow proof would otherwise write hundreds of megabytes before the first call.

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

- topic ``"instructions"``: ``target`` ("x86-64" or "cortex-m4"), ``compiler``, ``cam``, ``interp``,
  ``points``, ``step_counts``, ``net_stroke`` (N/D as text, "0" for none), ``queries``, ``instructions_runtime_inside``,
  ``instructions_runtime_wide``, ``instructions_minimal``, ``ratio_inside``, ``ratio_wide``,
  ``limit_inside`` (2), ``limit_wide`` (3), ``checksums_match``, ``met``, ``text``; or only
  ``target`` and ``text`` saying what was not measured and why (a missing tool is named);
- topic ``"cortex-m4"``: ``opt``, ``flash_bytes``, ``ram_bytes``, ``text_bytes``/``data_bytes``/``bss_bytes``,
  ``largest_frame``, ``frames``, ``stack_per_call`` (per measured table: position, slope, lookup,
  init), ``stack_per_call_max`` (tables without a net stroke), ``stack_per_call_max_net_stroke``
  (None in the quick run, which measures none), ``table_bytes``, ``pair_bytes``, ``text``; or a
  note naming the missing tool.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ecam.camfile import load_cam
from ecam.compile import compile_table
from ecam.table import KINDS, CamTable, narrow_horner

from ..firmware import FIRMWARE_DIR
from .cross import M4_FLAGS, M4_MACHINE, TARGETS, build, missing, run
from .plan import MASTER_COUNTS, SEED_CAM, STROKE_COUNTS, bench_profile

NET_STROKE_CAM = "rotary_knife"  # golden tables in firmware_tables/vectors with a net stroke
LIMITS = {"inside": 2.0, "wide": 3.0}
# The expanded form's quintic against the minimal precomputed lookup (issue 27), on both targets.
POLY_LIMITS = {"inside": 1.5, "wide": 2.0}
# Tables compiled with horner_bits=32 (the expanded form's narrow kernels on 32-bit cores): the
# seed cam at a stroke of 2^20 counts (the bench's 1e9-count stroke leaves no such format).
NARROW_CAM = "drrd-h32"
NARROW_STROKE_COUNTS = 2**20
# The golden rotary knife as a 32-bit core's firmware compiles it (horner_bits = 32 in its cam
# file's [table]), and with a period of 2^16 master counts (17 points, h = 4096), whose expanded
# form wraps any int64 master by a mask (full run only).
KNIFE_H32_CAM = "rotary_knife-h32"
KNIFE_POW2_CAM = "rotary_knife-2^16"
HOST_FLAGS = ("-O2", "-std=c99")
M4_OPTS = ("-Os", "-O2")
_SEED = 20261123


@dataclass(frozen=True)
class Measured:
    """Mean instructions per call (None where not measured) and how.

    With ``expanded`` measured too (issue 27): ``poly_inside``/``poly_wide`` for
    ``ecam_poly_position`` (the expanded form), ``expanded`` for its hand-written lookup
    (``ecam_minimal_expanded_<degree>``, the same bits) and ``q16`` for the minimal lookup with
    precomputed int32 coefficients and a Q16 fraction (``ecam_minimal_q16_<degree>``), the
    cheapest of the same degree; ``checksums_match`` then also covers poly == runtime (inside and
    wide) and expanded == poly."""

    runtime_inside: float
    runtime_wide: float
    minimal: float
    checksums_match: bool
    poly_inside: float | None = None
    poly_wide: float | None = None
    expanded: float | None = None
    q16: float | None = None

    @property
    def ratio_inside(self) -> float:
        return self.runtime_inside / self.minimal

    @property
    def ratio_wide(self) -> float:
        return self.runtime_wide / self.minimal

    @property
    def poly_ratio_inside(self) -> float:
        """Expanded form against the minimal precomputed lookup, masters inside the period."""
        return self.poly_inside / self.q16

    @property
    def poly_ratio_wide(self) -> float:
        """Expanded form (any int64 master) against the minimal precomputed lookup."""
        return self.poly_wide / self.q16

    @property
    def runtime_ratio_q16(self) -> float:
        """The Hermite runtime against the minimal precomputed lookup, inside the period."""
        return self.runtime_inside / self.q16


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


def _compile(compiler: str, flags: list, source: str, obj: Path, what: str, reuse: bool = True) -> Path:
    """FIRMWARE_DIR/source compiled to obj; with `reuse`, an existing obj is kept (the objects
    that do not depend on the table are built once per run; ecam_minimal.c, with its -D
    constants, is always rebuilt)."""
    if reuse and obj.is_file():
        return obj
    cmd = [compiler, *flags, "-I", str(FIRMWARE_DIR), "-c", str(FIRMWARE_DIR / source), "-o", str(obj)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=obj.parent, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError(f"{what} {source}: {(proc.stderr.strip().splitlines() or ['?'])[0]}")
    return obj


def host_counts(directory: Path, blob: bytes, fmt, count: int, shared: Path | None = None,
                expanded: bool = False) -> Measured:
    """x86-64 counts of one table (cc -O2), per call; ecam_table.o, ecam_target.o and its file
    reader ecam_host_io.o are built once into `shared` (default: `directory`). With `expanded`,
    the expanded form and the precomputed-coefficient yardsticks too."""
    cc = host_compiler()
    shared = shared or directory
    exe = directory / "ecam_count_host"
    objects = [_compile(cc, list(HOST_FLAGS), f"{stem}.c", shared / f"host_{stem}.o", "host build")
               for stem in ("ecam_target", "ecam_host_io", "ecam_table")]
    objects.append(_compile(cc, [*HOST_FLAGS, *minimal_defines(fmt)], "ecam_minimal.c", directory / "host_minimal.o",
                            "host build", reuse=False))  # fmt: skip
    proc = subprocess.run([cc, *map(str, objects), "-o", str(exe)], capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError(f"host link failed: {(proc.stderr.strip().splitlines() or ['?'])[0]}")
    (directory / "table.bin").write_bytes(blob)
    inside, wide = write_queries(directory, fmt.master_counts, count)
    name = fmt.interp
    runtime_in, out_in = _callgrind(exe, ["count", "table.bin", "runtime", inside], "ecam_table_position", directory)
    runtime_wide, out_wide = _callgrind(exe, ["count", "table.bin", "runtime", wide], "ecam_table_position", directory)
    minimal, out_min = _callgrind(exe, ["count", "table.bin", "minimal", inside], f"ecam_minimal_{name}", directory)
    match = out_in.split() == out_min.split()
    if not expanded:
        return Measured(runtime_in / count, runtime_wide / count, minimal / count, match)
    poly_in, out_poly = _callgrind(exe, ["count", "table.bin", "poly", inside], "ecam_poly_position", directory)
    poly_wide, out_poly_wide = _callgrind(exe, ["count", "table.bin", "poly", wide], "ecam_poly_position", directory)
    words, out_words = _callgrind(exe, ["count", "table.bin", "expanded", inside], f"ecam_minimal_expanded_{name}",
                                  directory)
    q16, _ = _callgrind(exe, ["count", "table.bin", "q16", inside], f"ecam_minimal_q16_{name}", directory)
    match = match and out_poly.split() == out_in.split() == out_words.split() and out_poly_wide.split() == out_wide.split()
    return Measured(runtime_in / count, runtime_wide / count, minimal / count, match, poly_in / count,
                    poly_wide / count, words / count, q16 / count)


# --- Cortex-M4: QEMU instruction trace -----------------------------------------------------------


def m4_note() -> str:
    """'' when Cortex-M4 figures can be taken, else which tool is missing."""
    why = missing(TARGETS["cortex-m4"])
    for tool in ("arm-none-eabi-size", "arm-none-eabi-nm", "arm-none-eabi-objdump"):
        package = "binutils-arm-none-eabi"
        if not why and shutil.which(tool) is None:
            why = f"cortex-m4: {tool} not found (Debian: apt-get install {package})"
    return why


def _objects(directory: Path, opt: str, defines: list, shared: Path | None = None) -> dict:
    """ecam_table.o, ecam_target.o, ecam_host_io.o (built once into `shared`) and ecam_minimal.o
    (with this table's constants, into `directory`) for the M4 at `opt`; their symbols delimit
    the counting, and -fstack-usage writes each one's frames next to it."""
    shared = shared or directory
    flags = [*M4_FLAGS, opt, "-fstack-usage"]
    out = {stem: _compile("arm-none-eabi-gcc", flags, f"{stem}.c", shared / f"m4{opt}_{stem}.o", "cortex-m4")
           for stem in ("ecam_table", "ecam_target", "ecam_host_io")}
    out["ecam_minimal"] = _compile("arm-none-eabi-gcc", [*flags, *defines], "ecam_minimal.c",
                                   directory / f"m4{opt}_ecam_minimal.o", "cortex-m4", reuse=False)  # fmt: skip
    return out


def _m4_link(directory: Path, opt: str, objects: dict, name: str) -> Path:
    """The count/stack driver for the M4 from the objects of :func:`_objects`."""
    sources = [str(objects[stem]) for stem in ("ecam_target", "ecam_host_io", "ecam_table", "ecam_minimal")]
    return build(TARGETS["cortex-m4"], directory / name, [opt], sources=sources)


def _functions(nm_target: Path) -> dict:
    """name -> (start, size) of every function of an object or ELF file."""
    proc = subprocess.run(["arm-none-eabi-nm", "-S", str(nm_target)], capture_output=True, text=True)
    out = {}
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "tT":
            out[parts[3]] = (int(parts[0], 16) & ~1, int(parts[1], 16))
    return out


# The loading API: what only these reach runs before any lookup (see lookup_ranges).
LOADER_ENTRIES = ("ecam_table_init", "ecam_pair_load")
_FUNCTION_HEAD = re.compile(r"^([0-9a-f]+) <([^>]+)>:$")
_DIRECT_BRANCH = re.compile(r"^\s*[0-9a-f]+:\s+b[a-z.]*\s+([0-9a-f]+) <")


def _direct_calls(elf: Path) -> dict:
    """function start -> starts of the other functions it branches to directly (bl, and b.w tail
    calls), from the ELF's disassembly. Indirect calls (blx rN, bx rN) are not in it."""
    proc = subprocess.run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)],
                          capture_output=True, text=True)  # fmt: skip
    if proc.returncode != 0:
        raise RuntimeError(f"arm-none-eabi-objdump: {(proc.stderr.strip().splitlines() or ['?'])[0]}")
    targets = {}
    current = None
    for line in proc.stdout.splitlines():
        head = _FUNCTION_HEAD.match(line)
        if head:
            current = targets.setdefault(int(head.group(1), 16), set())
            continue
        branch = _DIRECT_BRANCH.match(line)
        if branch and current is not None:
            current.add(int(branch.group(1), 16))
    return targets


def lookup_ranges(elf: Path, objects: list) -> list:
    """(start, size) of every function that can run in a lookup of the functions in `objects`.

    A lookup runs the functions of `objects` (the entry and, through the table's pointers, the
    kernels) and whatever they call directly, libgcc's helpers included. Left out: the functions
    only the loader reaches (direct calls from LOADER_ENTRIES: the CRC, the field rules, the
    overflow proof). They run before the first counted call, so tracing them would only fill the
    log (hundreds of megabytes for a table of thousands of points); a function that any other
    function of `objects` calls directly stays in, and the kernels, which the lookup calls
    through the table's pointers, are called by no loader function, so they stay in too."""
    functions = _functions(elf)
    ranges = sorted((start, size) for start, size in functions.values() if size)
    starts = [start for start, _ in ranges]

    def owner(address: int) -> int | None:
        k = int(np.searchsorted(starts, address, side="right")) - 1
        return starts[k] if k >= 0 and address < ranges[k][0] + ranges[k][1] else None

    edges = {start: {owner(t) for t in targets} - {None, start} for start, targets in _direct_calls(elf).items()}

    def closure(roots: set) -> set:
        seen, todo = set(), list(roots)
        while todo:
            f = todo.pop()
            if f not in seen:
                seen.add(f)
                todo.extend(edges.get(f, ()))
        return seen

    defined = set()
    for obj in objects:
        for name in _functions(obj):
            if name not in functions:
                raise RuntimeError(f"{name} of {Path(obj).name} is not in {elf.name}")
            defined.add(functions[name][0])
    loader = closure({functions[name][0] for name in LOADER_ENTRIES if name in functions} & defined)
    roots = defined - loader
    size = dict(ranges)
    return sorted((start, size[start]) for start in closure(roots))


def count_ranges(elf: Path, objects: list, entry: str) -> list:
    """What a count traces: :func:`lookup_ranges` plus the functions that call `entry` directly
    (the driver's loop), so that the log shows where each call returns."""
    functions = _functions(elf)
    target = functions[entry][0]
    callers = {start for start, targets in _direct_calls(elf).items() if target in targets}
    size = {start: n for start, n in functions.values()}
    return sorted(set(lookup_ranges(elf, objects)) | {(start, size[start]) for start in callers if size.get(start)})


def call_counts(elf: Path, trace: Path, entry: str) -> np.ndarray:
    """Instructions of each call of `entry`, in order: every logged instruction from the call
    until control is back in its caller, i.e. callgrind's inclusive count. QEMU's exec log with
    one instruction per translation block has one line per instruction ("[cs_base/pc/flags/
    cflags]"). On a log filtered by :func:`count_ranges` only the functions a lookup can run are
    seen; on an unfiltered log (slow: the whole program), everything: the tests compare both."""
    functions = _functions(elf)
    ranges = sorted((start, size) for start, size in functions.values() if size)
    starts = np.array([a for a, _ in ranges], dtype=np.int64)
    ends = np.array([a + n for a, n in ranges], dtype=np.int64)
    entry_address = functions[entry][0]
    pattern = re.compile(r"\[[0-9a-f]+/([0-9a-f]+)/")
    with trace.open() as log:
        pcs = np.array([int(m.group(1), 16) for m in map(pattern.search, log) if m], dtype=np.int64)
    slot = np.searchsorted(starts, pcs, side="right") - 1
    owner = np.where((slot >= 0) & (pcs < ends[np.clip(slot, 0, None)]), slot, -1)
    counts = []
    done = 0
    for start in np.flatnonzero(pcs == entry_address).tolist():
        if start < done:  # the entry again inside a call (none of the lookups does that)
            raise RuntimeError(f"{entry} re-entered within a call at trace line {start}")
        caller = owner[start - 1] if start else -1
        back = np.flatnonzero(owner[start:] == caller) if caller >= 0 else np.array([])
        if not back.size:
            raise RuntimeError(f"{entry} call at trace line {start} does not return to a traced caller")
        done = start + int(back[0])
        counts.append(done - start)
    return np.array(counts, dtype=np.int64)


def m4_counts(directory: Path, blob: bytes, fmt, count: int, opt: str = "-O2", shared: Path | None = None,
              expanded: bool = False) -> Measured:
    """Cortex-M4 counts of one table, per call; the objects that do not depend on the table are
    built once into `shared` (default: `directory`). Two QEMU runs: the runtime on both query
    sets (its calls split by position in the log), the minimal lookup on the inside set; with
    `expanded`, three more: the expanded form on both sets, and its two yardsticks."""
    target = TARGETS["cortex-m4"]
    objects = _objects(directory, opt, minimal_defines(fmt), shared)
    elf = _m4_link(directory, opt, objects, f"ecam_count_m4{opt}.elf")
    (directory / "table.bin").write_bytes(blob)
    inside, wide = write_queries(directory, fmt.master_counts, count)
    runs = {}
    subjects = [("runtime", "ecam_table_position", objects["ecam_table"], [inside, wide]),
                ("minimal", f"ecam_minimal_{fmt.interp}", objects["ecam_minimal"], [inside])]
    if expanded:
        subjects += [("poly", "ecam_poly_position", objects["ecam_table"], [inside, wide]),
                     ("expanded", f"ecam_minimal_expanded_{fmt.interp}", objects["ecam_minimal"], [inside]),
                     ("q16", f"ecam_minimal_q16_{fmt.interp}", objects["ecam_minimal"], [inside])]
    for what, entry, obj, queries in subjects:
        trace = directory / "trace.log"
        ranges = count_ranges(elf, [obj], entry)
        proc = run(target, elf, ["count", "table.bin", what, *queries], directory, trace=trace, ranges=ranges)
        if proc.returncode != 0:
            raise RuntimeError(f"cortex-m4 count {what}: exit {proc.returncode} {proc.stdout.strip()} {proc.stderr.strip()}")
        calls = call_counts(elf, trace, entry)
        trace.unlink()
        if calls.size != count * len(queries):
            raise RuntimeError(f"cortex-m4 trace saw {calls.size} calls of {entry}, expected {count * len(queries)}")
        runs[what] = ([float(calls[k * count:(k + 1) * count].mean()) for k in range(len(queries))],
                      proc.stdout.splitlines())
    (runtime_inside, runtime_wide), lines = runs["runtime"]
    (minimal,), minimal_lines = runs["minimal"]
    match = lines[0].split() == minimal_lines[0].split()
    if not expanded:
        return Measured(runtime_inside, runtime_wide, minimal, match)
    (poly_inside, poly_wide), poly_lines = runs["poly"]
    (words,), word_lines = runs["expanded"]
    (q16,), _ = runs["q16"]
    match = match and poly_lines == lines and word_lines[0].split() == lines[0].split()
    return Measured(runtime_inside, runtime_wide, minimal, match, poly_inside, poly_wide, words, q16)


def _stack_usage(su: Path) -> dict:
    """function -> frame bytes, from a -fstack-usage file."""
    out = {}
    for line in su.read_text().splitlines():
        parts = line.split("\t")
        if len(parts) >= 2:
            out[parts[0].rsplit(":", 1)[-1]] = int(parts[1])
    return out


def m4_footprint(directory: Path, blobs: dict, shared: Path | None = None) -> list[dict]:
    """Flash, RAM and stack of the runtime on the Cortex-M4 at -Os and -O2 (one dict each).
    `blobs`: name -> blob, for the measured (painted) stack of each API call on that table."""
    target = TARGETS["cortex-m4"]
    rng = np.random.default_rng(_SEED + 1)
    out = []
    for opt in M4_OPTS:
        objects = _objects(directory, opt, [], shared)
        size = subprocess.run(["arm-none-eabi-size", str(objects["ecam_table"])], capture_output=True, text=True)
        text, data, bss = (int(v) for v in size.stdout.splitlines()[1].split()[:3])
        frames = _stack_usage(objects["ecam_table"].with_suffix(".su"))
        kernel_frames = {name: frames[name] for name in frames if name != "ecam_slope_ok" and name.startswith(
            ("ecam_position_", "ecam_slope_", "ecam_table_position", "ecam_table_slope", "ecam_table_lookup",
             "ecam_general", "ecam_coefficient", "ecam_quintic", "ecam_cubic", "ecam_linear", "ecam_net_"))}  # fmt: skip
        elf = _m4_link(directory, opt, objects, f"ecam_stack_m4{opt}.elf")
        painted = {}
        sizes = {}
        for name, blob in blobs.items():
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
            painted[name] = {k: values[k] for k in ("position", "slope", "lookup", "init")}
            sizes = {k: values[k] for k in ("table_bytes", "pair_bytes")}
        out.append({"opt": opt, "flash_bytes": text + data, "ram_bytes": data + bss, "text_bytes": text,
                    "data_bytes": data, "bss_bytes": bss, "largest_frame": max(kernel_frames.values()), "frames": kernel_frames,
                    "stack_per_call": painted, **sizes})  # fmt: skip
    return out


# --- bench rows ----------------------------------------------------------------------------------


def bench_tables(quick: bool) -> list:
    """(cam, table) pairs measured: the seed cam at the bench scale, each kind at 145 points
    (h = 8192, a power of two); the full run adds 97 points (h = 12288, not a power of two) and
    the golden rotary-knife tables (a net stroke of 360000 counts per period, h = 3000), whose
    masters outside the period also take step 7."""
    profile = bench_profile(SEED_CAM)
    low, high = profile.slave_range
    scale = STROKE_COUNTS / (high - low)
    out = []
    for points in (145,) if quick else (145, 97):
        for kind in KINDS:
            out.append((SEED_CAM, compile_table(profile, interp=kind, points=points, master_counts=MASTER_COUNTS,
                                                slave_counts_per_unit=scale)))  # fmt: skip
    for kind in () if quick else KINDS:
        path = FIRMWARE_DIR / "vectors" / f"{NET_STROKE_CAM}_{kind}.bin"
        if path.is_file():
            out.append((NET_STROKE_CAM, CamTable.from_bytes(path.read_bytes())))
    for points in (145,) if quick else (145, 97):
        for kind in KINDS:
            out.append((NARROW_CAM, compile_table(profile, interp=kind, points=points, master_counts=MASTER_COUNTS,
                                                  slave_counts_per_unit=NARROW_STROKE_COUNTS / (high - low),
                                                  horner_bits=32)))  # fmt: skip
    if not quick:
        knife = load_cam(FIRMWARE_DIR / "cams" / f"{NET_STROKE_CAM}.toml")
        out += [(KNIFE_H32_CAM, compile_table(knife, interp="quintic", points=13, horner_bits=32)),
                (KNIFE_POW2_CAM, compile_table(knife, interp="quintic", points=17, master_counts=2**16,
                                               horner_bits=32))]
    return out


def _describe(cam: str, table) -> str:
    f = table.format
    net = f", net stroke {f.net_stroke_num}/{f.net_stroke_den}" if f.net_stroke_num else ""
    return f"{cam} {f.interp}, {f.points} points (h = {f.step_counts}{net})"


def _row(target: str, compiler: str, cam: str, table, m: Measured, count: int) -> dict:
    met = m.ratio_inside <= LIMITS["inside"] and m.ratio_wide <= LIMITS["wide"] and m.checksums_match
    text = (f"instructions per lookup, {target} ({compiler}), {_describe(cam, table)}: runtime {m.runtime_inside:.1f} "
            f"inside the period / {m.runtime_wide:.1f} any int64, minimal {m.minimal:.1f}: "
            f"{m.ratio_inside:.2f}x / {m.ratio_wide:.2f}x (limits {LIMITS['inside']:g}x / {LIMITS['wide']:g}x): "
            f"{'met' if met else 'MISSED'}{'' if m.checksums_match else '; CHECKSUMS DIFFER'}")
    row = {"kind": "note", "topic": "instructions", "target": target, "compiler": compiler, "cam": cam,
           "interp": table.interp, "points": table.points, "step_counts": table.format.step_counts,
           "net_stroke": str(table.format.net_stroke), "queries": count,
           "instructions_runtime_inside": m.runtime_inside,
           "instructions_runtime_wide": m.runtime_wide, "instructions_minimal": m.minimal,
           "ratio_inside": m.ratio_inside, "ratio_wide": m.ratio_wide, "limit_inside": LIMITS["inside"],
           "limit_wide": LIMITS["wide"], "checksums_match": m.checksums_match, "met": met, "text": text}  # fmt: skip
    if m.q16 is not None:
        quintic = table.interp == "quintic"
        poly_met = (m.poly_ratio_inside <= POLY_LIMITS["inside"] and m.poly_ratio_wide <= POLY_LIMITS["wide"]
                    if quintic else None)  # the limits are for the quintic
        row.update({"horner_bits": 32 if narrow_horner(table) else 64,
                    "instructions_poly_inside": m.poly_inside, "instructions_poly_wide": m.poly_wide,
                    "instructions_expanded": m.expanded, "instructions_q16": m.q16,
                    "ratio_poly_inside": m.poly_ratio_inside, "ratio_poly_wide": m.poly_ratio_wide,
                    "ratio_runtime_q16": m.runtime_ratio_q16,
                    "limit_poly_inside": POLY_LIMITS["inside"] if quintic else None,
                    "limit_poly_wide": POLY_LIMITS["wide"] if quintic else None, "poly_met": poly_met})
        row["text"] += (f"; expanded form {m.poly_inside:.1f} / {m.poly_wide:.1f}, its hand-written lookup "
                        f"{m.expanded:.1f}, minimal precomputed Q16 {m.q16:.1f}: {m.poly_ratio_inside:.2f}x / "
                        f"{m.poly_ratio_wide:.2f}x (Hermite runtime {m.runtime_ratio_q16:.2f}x)"
                        + ("" if poly_met is None else
                           f" (limits {POLY_LIMITS['inside']:g}x / {POLY_LIMITS['wide']:g}x): "
                           f"{'met' if poly_met else 'MISSED'}"))
    return row


def instruction_rows(directory: Path, quick: bool) -> list[dict]:
    """The bench's instruction and Cortex-M4 rows (kind "note", topics "instructions" and
    "cortex-m4"); a note saying which tool is missing where a target cannot be measured."""
    count = 200 if quick else 1000
    rows = []
    tables = bench_tables(quick)
    shared = directory / "shared"
    shared.mkdir()
    why = host_note()
    if why:
        rows.append({"kind": "note", "topic": "instructions", "target": "x86-64",
                     "text": f"instructions per lookup on x86-64 not measured: {why}"})
    else:
        for k, (cam, table) in enumerate(tables):
            work = directory / f"host_{k}"
            work.mkdir()
            try:
                measured = host_counts(work, table.to_bytes(), table.format, count, shared=shared, expanded=True)
                rows.append(_row("x86-64", "cc -O2, callgrind", cam, table, measured, count))
            except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
                rows.append({"kind": "note", "topic": "instructions", "target": "x86-64",
                             "text": f"instructions per lookup on x86-64, {_describe(cam, table)}: not measured: {exc}"})
    why = m4_note()
    if why:
        rows.append({"kind": "note", "topic": "cortex-m4", "target": "cortex-m4",
                     "text": f"Cortex-M4 figures (size, stack, instructions) not measured: {why}"})
        return rows
    for k, (cam, table) in enumerate(tables):
        work = directory / f"m4_{k}"
        work.mkdir()
        try:
            measured = m4_counts(work, table.to_bytes(), table.format, count, shared=shared, expanded=True)
            rows.append(_row("cortex-m4", f"arm-none-eabi-gcc -O2, QEMU {M4_MACHINE} trace", cam, table, measured, count))
        except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
            rows.append({"kind": "note", "topic": "instructions", "target": "cortex-m4",
                         "text": f"instructions per lookup on Cortex-M4, {_describe(cam, table)}: not measured: {exc}"})
    work = directory / "m4_footprint"
    work.mkdir()
    try:
        blobs = {f"{cam} {t.interp}{', net stroke' if t.format.net_stroke_num else ''}":
                 t.to_bytes() for cam, t in tables
                 if cam in (SEED_CAM, NET_STROKE_CAM, NARROW_CAM) and (t.points == 145 or t.format.net_stroke_num)}
        for f in m4_footprint(work, blobs, shared=shared):
            stack = f["stack_per_call"]
            apis = ("position", "slope", "lookup")
            worst = {api: max(stack[d][api] for d in stack if "net stroke" not in d) for api in apis}
            nets = [d for d in stack if "net stroke" in d]
            net = {api: max(stack[d][api] for d in nets) for api in apis} if nets else None
            text = (f"Cortex-M4 {f['opt']}: ecam_table.o flash {f['flash_bytes']} B, RAM {f['ram_bytes']} B (static); "
                    f"sizeof(ecam_table) {f['table_bytes']} B, ecam_table_pair {f['pair_bytes']} B; stack per call "
                    f"(measured) position {worst['position']} B, slope {worst['slope']} B, lookup {worst['lookup']} B"
                    + ("" if net is None else
                       f" ({net['position']} B, {net['slope']} B, {net['lookup']} B with a net stroke)")
                    + f"; init {max(v['init'] for v in stack.values())} B; "
                    f"largest frame {f['largest_frame']} B (-fstack-usage)")  # fmt: skip
            rows.append({"kind": "note", "topic": "cortex-m4", "target": "cortex-m4", **f,
                         "stack_per_call_max": worst, "stack_per_call_max_net_stroke": net, "text": text})
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        rows.append({"kind": "note", "topic": "cortex-m4", "target": "cortex-m4",
                     "text": f"Cortex-M4 footprint not measured: {exc}"})
    return rows
