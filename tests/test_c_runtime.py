"""The C reference runtime (firmware_tables/ecam_table.c) against FORMAT.md.

The runtime is compiled here with the system C compiler, once strict (-std=c99 -Wall -Wextra
-Werror) and once with AddressSanitizer + UndefinedBehaviorSanitizer, and driven through
firmware_tables/ecam_cli.c. The oracle is tests/c_blobs.py, an independent pure-Python writer and
reference lookup; when ecam.CamTable exists it is cross-checked too. Everything is seeded.
"""

from __future__ import annotations

import functools
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from ecam import CamTable

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import c_blobs as cb  # noqa: E402

# Builds and times C and runs the bench: the full suite only (quick subset: -m "not slow").
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware_tables"
RUNTIME = [FIRMWARE / "ecam_table.c"]
CLI_SOURCES = [FIRMWARE / "ecam_cli.c", FIRMWARE / "ecam_host_io.c", FIRMWARE / "ecam_table.c"]
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
SANITIZE_FLAGS = [
    "-std=c99", "-Wall", "-Wextra", "-Werror", "-O1", "-g", "-fno-omit-frame-pointer",
    "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
]  # fmt: skip
SANITIZER_ENV = {
    "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0:exitcode=99",
    "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1:exitcode=98",
}

# Every status of ecam_table.h: one per rejection rule (FORMAT.md), in the loader's order.
STATUS_NAMES = {
    0: "ECAM_OK", -1: "ECAM_E_SHORT", -2: "ECAM_E_MAGIC", -3: "ECAM_E_VERSION",
    -4: "ECAM_E_HEADER_SIZE", -5: "ECAM_E_HEADER_CRC", -6: "ECAM_E_FIELD", -7: "ECAM_E_LENGTH",
    -8: "ECAM_E_PAYLOAD_CRC", -9: "ECAM_E_NULL", -10: "ECAM_E_DEGREE", -11: "ECAM_E_FLAGS",
    -12: "ECAM_E_RESERVED", -13: "ECAM_E_POINTS", -14: "ECAM_E_MASTER_COUNTS",
    -15: "ECAM_E_STEP_COUNTS", -16: "ECAM_E_STEP_SHIFT", -17: "ECAM_E_TAU_BITS",
    -18: "ECAM_E_TAU_RECIP", -19: "ECAM_E_POSITION_BITS", -20: "ECAM_E_WORK_BITS",
    -21: "ECAM_E_SLOPE_BITS", -22: "ECAM_E_CURVATURE_BITS", -23: "ECAM_E_SLOPE_PRESHIFT",
    -24: "ECAM_E_PAYLOAD_BYTES", -25: "ECAM_E_POINT_RANGE", -26: "ECAM_E_HORNER_RANGE",
    -27: "ECAM_E_SUM_RANGE", -28: "ECAM_E_POSITION_RANGE", -29: "ECAM_E_SLOPE_HORNER_RANGE",
    -30: "ECAM_E_SLOPE_PRODUCT", -31: "ECAM_E_SLOPE_RANGE", -32: "ECAM_E_UNINITIALISED",
    -33: "ECAM_E_BUSY", -34: "ECAM_E_NET_STROKE", -35: "ECAM_E_BUFFER", -36: "ECAM_E_RAMP",
}  # fmt: skip
CODES = {name: code for code, name in STATUS_NAMES.items()}
OK, E_SHORT, E_MAGIC, E_VERSION = 0, -1, -2, -3
E_HEADER_SIZE, E_HEADER_CRC, E_LENGTH, E_PAYLOAD_CRC, E_NULL = -4, -5, -7, -8, -9
ECAM_INVALID = -(2**31)  # what a table that is not ready looks up

MAIN_QUERIES = 250_000  # x 4 tables (periodic or not, h = 2^k or not) = 1M per degree
EDGE_QUERIES = 20_000
SANITIZER_QUERIES = 50_000

# --------------------------------------------------------------------------------------------
# Builds
# --------------------------------------------------------------------------------------------


def _compiler() -> str | None:
    for name in (os.environ.get("CC", "cc"), "cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _compile(out: Path, sources: list, flags: list) -> Path:
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    cmd = [cc, *flags, "-I", str(FIRMWARE), "-o", str(out), *map(str, sources)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(cmd)}\n{proc.stderr}"
    assert proc.stderr == "", proc.stderr  # no warnings even where -Werror does not reach
    return out


def _require_sanitizers(build_dir: Path) -> None:
    """Skip (not fail) only when the toolchain itself cannot link a sanitized program."""
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    probe = build_dir / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    proc = subprocess.run(
        [cc, *SANITIZE_FLAGS, "-o", str(build_dir / "probe"), str(probe)], capture_output=True
    )
    if proc.returncode != 0:
        pytest.skip("the C compiler cannot link -fsanitize=address,undefined programs")


@pytest.fixture(scope="session")
def build_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("ecam_c")


@pytest.fixture(scope="session")
def cli(build_dir) -> Path:
    return _compile(build_dir / "ecam_cli", CLI_SOURCES, STRICT_FLAGS)


@pytest.fixture(scope="session")
def cli_asan(build_dir) -> Path:
    _require_sanitizers(build_dir)
    return _compile(build_dir / "ecam_cli_asan", CLI_SOURCES, SANITIZE_FLAGS)


# --------------------------------------------------------------------------------------------
# Test tables
# --------------------------------------------------------------------------------------------

# name -> (M, N): power-of-two and other steps, tiny and maximal periods.
GEOMETRIES = {
    "pow2": (2**20, 64),  # h = 2^14
    "nonpow2": (360_000, 60),  # h = 6000
    "h1": (2, 2),  # smallest period, h = 1, F = 0
    "h3": (3, 1),  # one interval, h = 3
    "M2^31": (2**31, 2),  # largest period, h = 2^30
    "M2^31-2": (2_147_483_646, 42),  # h = 51130563, not a power of two, F >= 26
    "3*2^29": (3 * 2**29, 2),  # h = 3 * 2^28, F = 30
}
MAIN_CASES = [
    (degree, periodic, geometry)
    for degree in (1, 3, 5)
    for periodic in (True, False)
    for geometry in ("pow2", "nonpow2")
]
SHIFT_EXTREMES = {"P84": 84, "P23": 23}
EDGE_CASES = [
    (degree, periodic, geometry)
    for degree in (1, 3, 5)
    for periodic in (True, False)
    for geometry in ("h1", "h3", "M2^31", "M2^31-2", "3*2^29")
] + [(3, periodic, geometry) for periodic in (True, False) for geometry in SHIFT_EXTREMES]


def _case_id(case) -> str:
    degree, periodic, geometry = case
    return f"deg{degree}-{'periodic' if periodic else 'clamped'}-{geometry}"


def _seed(case) -> int:
    degree, periodic, geometry = case
    index = list(GEOMETRIES).index(geometry) if geometry in GEOMETRIES else 99
    return 1000 * degree + 100 * periodic + index


def shift_extreme_table(periodic: bool, preshift: int) -> cb.Table:
    """F = 30, W = 40: P = 84 shifts a 64-bit word by more than 63 (exactly 0 or -1 by the
    spec's floor), P = 23 makes the final slope shift 16 + F + W - P = 63."""
    return cb.Table(
        degree=3, periodic=periodic, master_counts=2 * 805_306_367,  # h not a power of two
        tau_bits=30, work_bits=40, slope_bits=40, curvature_bits=0, slope_preshift=preshift,
        position_bits=30, position=(-(2**16), 2**16, 0), slope=(2**27, -(2**27), 12345),
    )  # fmt: skip


@functools.lru_cache(maxsize=None)
def case_data(case) -> tuple:
    """(table, blob, queries, expected (n, 2) array) of one case, computed once per session."""
    degree, periodic, geometry = case
    rng = np.random.default_rng(_seed(case))
    if geometry in SHIFT_EXTREMES:
        table = shift_extreme_table(periodic, SHIFT_EXTREMES[geometry])
        count = EDGE_QUERIES
    else:
        M, N = GEOMETRIES[geometry]
        table = cb.random_table(rng, degree, periodic, M, N)
        count = MAIN_QUERIES if geometry in ("pow2", "nonpow2") else EDGE_QUERIES
    cb.certify(table)
    queries = cb.random_queries(rng, table, count)
    expected = np.array([cb.reference_lookup(table, m) for m in queries.tolist()], dtype=np.int64)
    return table, cb.make_blob(table), queries, expected


def write_blob(directory: Path, name: str, blob: bytes) -> Path:
    path = directory / name
    path.write_bytes(blob)
    return path


def run_cli(cli: Path, args: list, stdin: bytes = b"", sanitized: bool = False):
    env = dict(os.environ, **SANITIZER_ENV) if sanitized else None
    proc = subprocess.run([str(cli), *map(str, args)], input=stdin, capture_output=True, env=env)
    if sanitized:
        assert proc.returncode not in (98, 99), proc.stderr.decode(errors="replace")[-4000:]
        assert proc.stderr == b"", proc.stderr.decode(errors="replace")[-4000:]
    return proc


def c_lookups(cli: Path, blob_path: Path, queries: np.ndarray, sanitized=False) -> np.ndarray:
    """All queries through one ecam_cli process; returns an (n, 2) array (position, slope)."""
    stdin = ("\n".join(map(str, queries.tolist())) + "\n").encode()
    proc = run_cli(cli, [blob_path], stdin, sanitized)
    assert proc.returncode == 0, proc.stdout[:200] + proc.stderr[-2000:]
    out = np.array(proc.stdout.split(), dtype=np.int64)
    assert out.size == 2 * queries.size
    return out.reshape(-1, 2)


def assert_same(queries: np.ndarray, got: np.ndarray, expected: np.ndarray, what: str) -> None:
    bad = np.flatnonzero((got != expected).any(axis=1))
    if bad.size:
        rows = [
            f"m={queries[j]} got={tuple(got[j])} expected={tuple(expected[j])}" for j in bad[:10]
        ]
        pytest.fail(f"{what}: {bad.size} of {queries.size} lookups differ:\n" + "\n".join(rows))


def c_checks(cli: Path, paths: list, sanitized: bool = False) -> list:
    """Status code of each blob via one `ecam_cli --check` process."""
    proc = run_cli(cli, ["--check", *paths], sanitized=sanitized)
    lines = proc.stdout.decode().splitlines()
    assert len(lines) == len(paths), proc.stdout + proc.stderr
    codes = []
    for line in lines:
        if line == "ok":
            codes.append(OK)
        else:
            word, code, name = line.split()
            assert word == "error" and STATUS_NAMES[int(code)] == name, line
            codes.append(int(code))
    assert proc.returncode == (0 if all(c == OK for c in codes) else 1)
    return codes


# --------------------------------------------------------------------------------------------
# The oracle itself
# --------------------------------------------------------------------------------------------


def _rounded(stored: int, qy: int) -> int:
    """A stored Q(Qy) position in whole counts, rounded half up."""
    return (stored + (1 << qy >> 1)) >> qy


def linear_table(master_counts: int, tau_bits: int, position: tuple, **fields) -> cb.Table:
    values = dict(degree=1, periodic=True, master_counts=master_counts, tau_bits=tau_bits,
                  work_bits=0, slope_bits=0, curvature_bits=0, slope_preshift=0,
                  position_bits=0, position=position)  # fmt: skip
    values.update(fields)
    return cb.Table(**values)


def test_reference_hits_spec_identities():
    """Sanity of the Python oracle: grid points reproduce the stored positions, rounded from
    Q(Qy); clamped ends hold; certify() refuses an overflowing table."""
    for qy in (0, 7, 30):
        rng = np.random.default_rng(7 + qy)
        table = cb.random_table(rng, 3, True, 360_000, 60, tau_bits=13, position_bits=qy)
        h = table.step_counts
        for i in range(table.intervals):
            expected = _rounded(table.position[i], qy)
            assert cb.reference_lookup(table, i * h)[0] == expected
            assert cb.reference_lookup(table, i * h + 360_000 * 5)[0] == expected
    clamped = cb.random_table(np.random.default_rng(8), 5, False, 2**20, 64, position_bits=3)
    assert cb.reference_lookup(clamped, -1) == (_rounded(clamped.position[0], 3), 0)
    assert cb.reference_lookup(clamped, 2**20) == (_rounded(clamped.position[-1], 3), 0)
    with pytest.raises(OverflowError):
        cb.certify(linear_table(4, 1, (-(2**31), 2**31 - 1, 0)))


# --------------------------------------------------------------------------------------------
# Bit-for-bit lookups
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", MAIN_CASES, ids=_case_id)
def test_lookup_matches_reference(cli, build_dir, case):
    table, blob, queries, expected = case_data(case)
    assert queries.size >= MAIN_QUERIES
    path = write_blob(build_dir, _case_id(case) + ".ecam", blob)
    assert_same(queries, c_lookups(cli, path, queries), expected, _case_id(case))


@pytest.mark.parametrize("case", EDGE_CASES, ids=_case_id)
def test_lookup_matches_reference_edge_geometries(cli, build_dir, case):
    table, blob, queries, expected = case_data(case)
    path = write_blob(build_dir, _case_id(case) + ".ecam", blob)
    assert_same(queries, c_lookups(cli, path, queries), expected, _case_id(case))


@pytest.mark.parametrize("case", MAIN_CASES + EDGE_CASES, ids=_case_id)
def test_sanitized_lookup(cli_asan, build_dir, case):
    table, blob, queries, expected = case_data(case)
    n = min(SANITIZER_QUERIES, queries.size)  # the edge values come first
    path = write_blob(build_dir, "asan-" + _case_id(case) + ".ecam", blob)
    got = c_lookups(cli_asan, path, queries[:n], sanitized=True)
    assert_same(queries[:n], got, expected[:n], "sanitized " + _case_id(case))


def test_floor_modulo_over_many_periods(cli, build_dir):
    """Identity tables (linear, h = 2^k, position[i] = i * h, Qy = W = 0) return m mod M itself,
    and slope 1.0 in Q16, so the divide-free period wrap is checked against Python's % for many
    moduli M = N * 2^k."""
    rng = np.random.default_rng(77)
    periods = [(1, 1), (3, 0), (4095, 19), (2**31 - 1 >> 12, 12), (1, 30), (2047, 20)]
    while len(periods) < 64:
        n = int(rng.integers(1, 4097))
        k = int(rng.integers(0, 31 - n.bit_length()))
        periods.append((n, k))
    for n, k in periods:
        h = 1 << k
        M = n * h
        if M < 2:
            n, M = 2, 2 * h
        table = linear_table(M, k, tuple(i * h for i in range(n + 1)))
        queries = np.concatenate([
            np.array(cb.edge_queries(table), dtype=np.int64),
            rng.integers(cb.INT64_MIN, cb.INT64_MAX, 2000, dtype=np.int64, endpoint=True),
        ])  # fmt: skip
        path = write_blob(build_dir, "identity.ecam", cb.make_blob(table))
        got = c_lookups(cli, path, queries)
        expected = np.array([[m % M, 1 << 16] for m in queries.tolist()], dtype=np.int64)
        assert_same(queries, got, expected, f"m mod {M} (N={n}, h=2^{k})")


def test_misaligned_blob_and_api(build_dir):
    """Direct API use: NULL handling, failed-init tables, the one-output wrappers, a blob at an
    odd address, ecam_crc32 and ecam_status_name."""
    harness = build_dir / "api_harness.c"
    harness.write_text(API_HARNESS)
    table, blob, queries, expected = case_data((5, True, "nonpow2"))
    path = write_blob(build_dir, "api.ecam", blob)
    sample = queries[:2000]
    stdin = ("\n".join(map(str, sample.tolist())) + "\n").encode()
    for label, flags in (("strict", STRICT_FLAGS), ("asan", SANITIZE_FLAGS)):
        if label == "asan":
            _require_sanitizers(build_dir)
        exe = _compile(build_dir / f"api_harness_{label}", [harness, *RUNTIME], flags)
        proc = run_cli(exe, [path], stdin, sanitized=(label == "asan"))
        assert proc.returncode == 0, proc.stdout + proc.stderr
        lines = proc.stdout.decode().splitlines()
        head = dict(line.split("=", 1) for line in lines if "=" in line)
        rows = np.array([line.split() for line in lines if "=" not in line], dtype=np.int64)
        assert_same(sample, rows, expected[:2000], f"api harness {label}")
        assert head["crc_check"] == f"{zlib.crc32(b'123456789'):08x}"
        assert head["crc_empty"] == "00000000"
        assert head["crc_blob"] == f"{zlib.crc32(blob):08x}"
        assert head["init_null_table"] == str(E_NULL)
        assert head["init_null_blob"] == str(E_NULL)
        invalid4 = " ".join([str(ECAM_INVALID)] * 4)
        # A failed init: not ready, remembers why, every lookup is ECAM_INVALID (never a 0 command)
        assert head["failed_table_lookup"] == invalid4
        assert head["failed_table_state"] == f"ready=0 status={E_LENGTH}"
        assert head["null_blob_state"] == f"ready=0 status={E_NULL}"
        assert head["null_table_lookup"] == invalid4
        assert head["null_table_state"] == f"ready=0 status={E_NULL}"
        # A zero-filled table that was never initialised (static storage) behaves the same
        assert head["uninitialised_lookup"] == invalid4
        assert head["uninitialised_state"] == f"ready=0 status={CODES['ECAM_E_UNINITIALISED']}"
        # A good table that is re-initialised with a bad blob is no longer ready
        assert head["reinit_failed"] == f"{E_HEADER_CRC} ready=0 {ECAM_INVALID}"
        assert head["misaligned_init"] == "0"
        assert head["ready_state"] == "ready=1 status=0"
        for code, name in STATUS_NAMES.items():
            assert head[f"name{code}"] == name
        assert head["name1"] == head["name-37"] == head["name-100"] == "ECAM_E_UNKNOWN"


API_HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <inttypes.h>
#include "ecam_table.h"

int main(int argc, char **argv)
{
    static uint8_t storage[1 << 16];
    static uint8_t broken[1 << 16];
    static ecam_table never_initialised; /* zero-filled */
    uint8_t *blob = storage + 1; /* deliberately misaligned */
    ecam_table t, failed, reinit;
    size_t len;
    int32_t p, s, p2, s2;
    long long m;
    int code;
    FILE *f = fopen(argv[argc - 1], "rb");

    if (f == NULL) return 3;
    len = fread(blob, 1, sizeof storage - 1, f);
    fclose(f);
    printf("crc_check=%08" PRIx32 "\n", ecam_crc32((const uint8_t *)"123456789", 9));
    printf("crc_empty=%08" PRIx32 "\n", ecam_crc32(NULL, 0));
    printf("crc_blob=%08" PRIx32 "\n", ecam_crc32(blob, len));
    printf("init_null_table=%d\n", ecam_table_init(NULL, blob, len));
    printf("init_null_blob=%d\n", ecam_table_init(&t, NULL, len));
    printf("null_blob_state=ready=%d status=%d\n", ecam_table_ready(&t), ecam_table_status(&t));
    ecam_table_init(&failed, blob, len - 1);
    ecam_table_lookup(&failed, 12345, &p, &s);
    printf("failed_table_lookup=%d %d %d %d\n", (int)p, (int)s,
           (int)ecam_table_position(&failed, 7), (int)ecam_table_slope(&failed, 7));
    printf("failed_table_state=ready=%d status=%d\n", ecam_table_ready(&failed),
           ecam_table_status(&failed));
    ecam_table_lookup(NULL, 12345, &p, &s);
    printf("null_table_lookup=%d %d %d %d\n", (int)p, (int)s,
           (int)ecam_table_position(NULL, 7), (int)ecam_table_slope(NULL, 7));
    printf("null_table_state=ready=%d status=%d\n", ecam_table_ready(NULL), ecam_table_status(NULL));
    ecam_table_lookup(&never_initialised, 12345, &p, &s);
    printf("uninitialised_lookup=%d %d %d %d\n", (int)p, (int)s,
           (int)ecam_table_position(&never_initialised, 7), (int)ecam_table_slope(&never_initialised, 7));
    printf("uninitialised_state=ready=%d status=%d\n", ecam_table_ready(&never_initialised),
           ecam_table_status(&never_initialised));
    memcpy(broken, blob, len);
    broken[20] ^= 1u; /* header byte: CRC mismatch */
    if (ecam_table_init(&reinit, blob, len) != 0) return 8;
    code = ecam_table_init(&reinit, broken, len);
    printf("reinit_failed=%d ready=%d %d\n", code, ecam_table_ready(&reinit),
           (int)ecam_table_position(&reinit, 0));
    for (code = -37; code <= 1; code++) printf("name%d=%s\n", code, ecam_status_name(code));
    printf("name-100=%s\n", ecam_status_name(-100));
    printf("misaligned_init=%d\n", ecam_table_init(&t, blob, len));
    printf("ready_state=ready=%d status=%d\n", ecam_table_ready(&t), ecam_table_status(&t));
    while (scanf("%lld", &m) == 1) {
        ecam_table_lookup(&t, (int64_t)m, &p, &s);
        ecam_table_lookup(&t, (int64_t)m, NULL, NULL);
        ecam_table_lookup(&t, (int64_t)m, &p2, NULL);
        if (p2 != p) return 4;
        ecam_table_lookup(&t, (int64_t)m, NULL, &s2);
        if (s2 != s) return 5;
        if (ecam_table_position(&t, (int64_t)m) != p) return 6;
        if (ecam_table_slope(&t, (int64_t)m) != s) return 7;
        printf("%" PRId32 " %" PRId32 "\n", p, s);
    }
    return 0;
}
"""


# --------------------------------------------------------------------------------------------
# Loader: corruption, truncation and every field rule
# --------------------------------------------------------------------------------------------


def small_table(degree: int) -> cb.Table:
    """Three points, so every byte of every payload array is covered cheaply."""
    return cb.random_table(np.random.default_rng(40 + degree), degree, True, 3000, 2)


def corruption_set(degree: int) -> list:
    """(name, blob, expected status) for every single-byte change, truncation and one extension."""
    blob = cb.make_blob(small_table(degree))
    out = []
    for offset in range(len(blob)):
        if offset < 4:
            expected = E_MAGIC
        elif offset < 6:
            expected = E_VERSION
        elif offset < 8:
            expected = E_HEADER_SIZE
        elif offset < 64:
            expected = E_HEADER_CRC
        else:
            expected = E_PAYLOAD_CRC
        for mask in (0x01, 0xFF):
            bad = bytearray(blob)
            bad[offset] ^= mask
            out.append((f"xor{mask:02x}@{offset}", bytes(bad), expected))
    for length in range(len(blob)):
        out.append((f"len{length}", blob[:length], E_SHORT if length < 64 else E_LENGTH))
    out.append(("appended", blob + b"\x00", E_LENGTH))
    out.append(("valid", blob, OK))
    return out


def _check_all(cli, build_dir: Path, cases: list, prefix: str, sanitized=False) -> None:
    directory = build_dir / prefix
    directory.mkdir(exist_ok=True)
    paths = [write_blob(directory, f"{k:04d}.ecam", blob) for k, (_, blob, _) in enumerate(cases)]
    got = c_checks(cli, paths, sanitized)
    wrong = [f"{name}: got {g}, expected {e}" for (name, _, e), g in zip(cases, got) if g != e]
    assert not wrong, f"{len(wrong)} of {len(cases)} blobs misjudged:\n" + "\n".join(wrong[:20])


@pytest.mark.parametrize("degree", (1, 3, 5))
def test_every_corruption_is_rejected(cli, build_dir, degree):
    cases = corruption_set(degree)
    assert sum(1 for _, _, e in cases if e != OK) >= 3 * 76
    _check_all(cli, build_dir, cases, f"corrupt{degree}")


@pytest.mark.parametrize("degree", (1, 3, 5))
def test_every_corruption_is_rejected_sanitized(cli_asan, build_dir, degree):
    _check_all(cli_asan, build_dir, corruption_set(degree), f"corrupt_asan{degree}", True)


def _recip(h: int, F: int) -> int:
    return -(-(1 << (32 + F)) // h)


def zero_table(degree: int, master_counts: int = 3000, intervals: int = 2, **fields) -> cb.Table:
    """A table whose payload is all zero: its overflow proof depends on the header alone, so
    the format rules can be probed at their edges with known outcomes."""
    points = intervals + 1
    h = master_counts // intervals
    F = cb.ceil_log2(h)
    values = dict(degree=degree, periodic=True, master_counts=master_counts, tau_bits=F,
                  work_bits=0, slope_bits=0, curvature_bits=0, slope_preshift=0, position_bits=0,
                  position=(0,) * points, slope=(0,) * points if degree >= 3 else (),
                  curvature=(0,) * points if degree == 5 else ())  # fmt: skip
    values.update(fields)
    return cb.Table(**values)


def parse_blob(blob: bytes) -> cb.Table:
    """A blob that passes every field rule, back as a c_blobs.Table (header fields as stored)."""
    names = [name for name, _ in cb.HEADER_FIELDS]
    v = dict(zip(names, cb.HEADER_STRUCT.unpack(blob[:60])))
    n, degree = v["points"], v["degree"]
    arrays = [struct.unpack_from(f"<{n}i", blob, 64 + 4 * n * k) for k in range(3)[: (degree + 1) // 2]]
    return cb.Table(
        degree=degree, periodic=bool(v["flags"] & 1), master_counts=v["master_counts"],
        tau_bits=v["tau_bits"], work_bits=v["work_bits"], slope_bits=v["slope_bits"],
        curvature_bits=v["curvature_bits"], slope_preshift=v["slope_preshift"],
        position_bits=v["position_bits"], position=arrays[0],
        slope=arrays[1] if degree >= 3 else (), curvature=arrays[2] if degree == 5 else (),
    )  # fmt: skip


def proof_status(blob: bytes) -> int:
    """OK, or the code of the first overflow-proof rule the blob breaks, by tests/c_blobs.py's
    independent reading of FORMAT.md."""
    failure = cb.proof_failure(parse_blob(blob))
    return OK if failure is None else CODES[failure[0]]


PROOF = "decided by the overflow proof (c_blobs.proof_failure)"


def field_rule_set() -> list:
    """(name, blob, expected) for each rule of FORMAT.md, with a valid header CRC, plus valid
    blobs at the edges of each rule as positive controls. Each rule has its own code; where a
    blob passes every field rule its status is the overflow proof's (PROOF)."""
    linear = small_table(1)  # h = 1500, not a power of two
    cubic = small_table(3)
    quintic = small_table(5)
    pow2 = cb.random_table(np.random.default_rng(50), 3, True, 2**12, 4)  # h = 1024
    zero_cubic, zero_quintic, zero_linear = zero_table(3), zero_table(5), zero_table(1)
    h = cubic.step_counts
    out = []

    def add(name, expected, table=cubic, **fields):
        blob = cb.make_blob(table, **fields)
        out.append((name, blob, proof_status(blob) if expected is PROOF else expected))

    # The envelope checks, in FORMAT.md order.
    add("magic", E_MAGIC, magic=b"ECAm")
    for version in (0, 4, 0x0103, 0x0201):
        add(f"version{version}", E_VERSION, format_version=version)
    for size in (0, 63, 65, 128):
        add(f"header_bytes{size}", E_HEADER_SIZE, header_bytes=size)
    good = cb.make_blob(cubic)
    out.append(("header_crc", cb.patch(good, 60, struct.pack("<I", 0), False), E_HEADER_CRC))
    # degree and flags
    for degree in (0, 2, 4, 6, 7, 255):
        add(f"degree{degree}", CODES["ECAM_E_DEGREE"], degree=degree)
    add("degree3_as_5", CODES["ECAM_E_PAYLOAD_BYTES"], degree=5)  # payload_bytes is not points * 12
    for flags in (2, 3, 0x80, 0xFE):
        add(f"flags{flags:#x}", CODES["ECAM_E_FLAGS"], flags=flags)
    add("flags0", OK, flags=0)
    # step_shift and tau_bits
    for shift in (-2, 0, 10, 11, 127, -128):
        add(f"step_shift{shift}", CODES["ECAM_E_STEP_SHIFT"], step_shift=shift)
    for shift in (-1, 9, 11):
        add(f"pow2_step_shift{shift}", CODES["ECAM_E_STEP_SHIFT"], table=pow2, step_shift=shift)
    lowest = cb.ceil_log2(h)
    add("tau_bits_below_log2h", CODES["ECAM_E_TAU_BITS"], tau_bits=lowest - 1,
        tau_recip=_recip(h, lowest - 1))  # fmt: skip
    for F in (lowest, 30):  # on a zero payload only the shifts decide the proof
        for P in (max(0, 16 + F - 63), 16 + F):
            expected = OK if P < 16 + F else CODES["ECAM_E_SLOPE_RANGE"]  # P = 16+F+W: R > 2^31
            add(f"tau_bits{F}_P{P}", expected, table=zero_cubic, tau_bits=F, tau_recip=_recip(h, F),
                slope_preshift=P)  # fmt: skip
    add("tau_bits31", CODES["ECAM_E_TAU_BITS"], tau_bits=31, tau_recip=_recip(h, 31))
    add("pow2_tau_bits_k+1", CODES["ECAM_E_TAU_BITS"], table=pow2, tau_bits=11, tau_recip=_recip(1024, 11))
    add("pow2_tau_bits_k-1", CODES["ECAM_E_TAU_BITS"], table=pow2, tau_bits=9, tau_recip=_recip(1024, 9))
    # Qy, W, Qa, Qb on zero payloads; P is the smallest that keeps 16 + F + W - P <= 63
    F = zero_cubic.tau_bits

    def bits(qy, w, **more):
        return dict(position_bits=qy, work_bits=w, slope_bits=0, slope_preshift=max(0, 16 + F + w - 63), **more)

    add("work_bits41", CODES["ECAM_E_WORK_BITS"], table=zero_cubic, **bits(0, 41))
    add("work_bits40", OK, table=zero_cubic, **bits(0, 40))
    add("position_bits31", CODES["ECAM_E_POSITION_BITS"], table=zero_cubic, **bits(31, 40))
    add("position_bits30", OK, table=zero_cubic, **bits(30, 40))
    add("work_bits_below_Qy", CODES["ECAM_E_WORK_BITS"], table=zero_cubic, **bits(11, 10))
    add("work_bits_eq_Qy", OK, table=zero_cubic, **bits(10, 10))
    add("slope_bits_gt_W", CODES["ECAM_E_SLOPE_BITS"], table=zero_cubic, **dict(bits(5, 20), slope_bits=21))
    add("slope_bits_eq_W", OK, table=zero_cubic, **dict(bits(5, 20), slope_bits=20))
    add("cubic_curvature_bits1", CODES["ECAM_E_CURVATURE_BITS"], curvature_bits=1)
    add("curvature_bits_gt_W", CODES["ECAM_E_CURVATURE_BITS"], table=zero_quintic,
        **bits(0, 20, curvature_bits=21))  # fmt: skip
    add("quintic_bits_eq_W", OK, table=zero_quintic, **dict(bits(20, 20, curvature_bits=20), slope_bits=20))
    lf = zero_linear.tau_bits
    for qy, w, expected in ((5, 5, OK), (5, 6, "ECAM_E_WORK_BITS"), (6, 5, "ECAM_E_WORK_BITS"),
                            (0, 1, "ECAM_E_WORK_BITS")):  # fmt: skip
        add(f"linear_Qy{qy}_W{w}", expected if expected == OK else CODES[expected], table=zero_linear,
            position_bits=qy, work_bits=w, slope_preshift=max(0, 16 + lf + w - 63))  # fmt: skip
    add("linear_slope_bits1", CODES["ECAM_E_SLOPE_BITS"], table=linear, slope_bits=1)
    add("linear_curvature_bits1", CODES["ECAM_E_CURVATURE_BITS"], table=linear, curvature_bits=1)
    # P: 16 + F + W - P in 0..63; P itself may exceed 63 (the proof then decides, with the header's P)
    W = cubic.work_bits
    add("P_too_large", CODES["ECAM_E_SLOPE_PRESHIFT"], slope_preshift=16 + cubic.tau_bits + W + 1)
    add("P_max", PROOF, slope_preshift=16 + cubic.tau_bits + W)
    f30 = dict(tau_bits=30, tau_recip=_recip(h, 30), work_bits=40, slope_bits=0)  # 16+F+W = 86
    for P, expected in ((22, CODES["ECAM_E_SLOPE_PRESHIFT"]), (23, OK), (64, PROOF), (86, PROOF),
                        (87, CODES["ECAM_E_SLOPE_PRESHIFT"])):  # fmt: skip
        add(f"F30_W40_P{P}", expected, table=zero_cubic, slope_preshift=P, **f30)
    big = dict(tau_bits=30, tau_recip=_recip(h, 30), work_bits=20, slope_bits=0)  # 16+F+W = 66
    add("P_too_small", CODES["ECAM_E_SLOPE_PRESHIFT"], table=zero_cubic, slope_preshift=2, **big)
    add("P_min", OK, table=zero_cubic, slope_preshift=3, **big)
    # points, M, h
    add("points1", CODES["ECAM_E_POINTS"], points=1)
    add("points4", CODES["ECAM_E_STEP_COUNTS"], points=4)  # 3 * h != M
    add("master_counts_off", CODES["ECAM_E_STEP_COUNTS"], master_counts=3001)
    add("master_counts_2^31+1", CODES["ECAM_E_MASTER_COUNTS"], master_counts=2**31 + 1)
    add("step_counts_off", CODES["ECAM_E_STEP_COUNTS"], step_counts=1501, tau_recip=_recip(1501, F))
    add("step_counts0", CODES["ECAM_E_STEP_COUNTS"], step_counts=0)
    for name, table, expected in (
        ("master_counts1", linear_table(1, 0, (0, 0)), "ECAM_E_MASTER_COUNTS"),  # N * h == M holds
        ("master_counts2", linear_table(2, 0, (0, 0, 0)), "ECAM_OK"),
        ("master_counts2^31", linear_table(2**31, 30, (0, 0, 0)), "ECAM_OK"),
        ("master_counts3*2^30", linear_table(3 * 2**30, 30, (0, 0, 0, 0)), "ECAM_E_MASTER_COUNTS"),
        ("step_counts2^31", linear_table(2**31, 31, (0, 0)), "ECAM_E_STEP_COUNTS"),  # h > 2^30
    ):
        out.append((name, cb.make_blob(table), CODES[expected]))
    # payload_bytes that only matches modulo 2^32: points * 12 for points = 2^30 + 1
    values = dict(quintic.header_values(), points=2**30 + 1, master_counts=2**31,
                  step_counts=2, step_shift=1, tau_bits=1, tau_recip=2**32, slope_preshift=0,
                  payload_bytes=((2**30 + 1) * 12) % 2**32)  # fmt: skip
    payload = bytes(values["payload_bytes"])
    values["payload_crc32"] = zlib.crc32(payload)
    out.append(("payload_bytes_mod_2^32", cb.pack_blob(values, payload), CODES["ECAM_E_PAYLOAD_BYTES"]))
    # reserved
    for k in range(3):
        add(f"reserved29+{k}", CODES["ECAM_E_RESERVED"], reserved_29=bytes(k) + b"\x80" + bytes(2 - k))
    for k in range(12):
        add(f"reserved48+{k}", CODES["ECAM_E_RESERVED"], reserved_48=bytes(k) + b"\x01" + bytes(11 - k))
    # tau_recip
    R = cubic.tau_recip
    for delta in (-1, 1, 2**32):
        add(f"tau_recip{delta:+d}", CODES["ECAM_E_TAU_RECIP"], tau_recip=R + delta)
    for value in (0, 2**64 - 1, 2**63):
        add(f"tau_recip={value:#x}", CODES["ECAM_E_TAU_RECIP"], tau_recip=value)
    add("pow2_tau_recip+1", CODES["ECAM_E_TAU_RECIP"], table=pow2, tau_recip=2**32 + 1)
    add("pow2_tau_recip-1", CODES["ECAM_E_TAU_RECIP"], table=pow2, tau_recip=2**32 - 1)
    # payload_bytes vs length vs payload CRC
    n_bytes = len(cubic.payload())
    for delta in (-4, -1, 1, 4):  # total length kept consistent, so only the field rule fails
        blob = cb.make_blob(cubic, payload_bytes=n_bytes + delta)
        blob = blob[: 64 + n_bytes + delta] + bytes(max(delta, 0))
        out.append((f"payload_bytes{delta:+d}", blob, CODES["ECAM_E_PAYLOAD_BYTES"]))
    out.append(("length_only", good + b"\x00\x00\x00\x00", E_LENGTH))
    add("payload_crc", E_PAYLOAD_CRC, payload_crc32=cubic.header_values()["payload_crc32"] ^ 1)
    # version 2: the net stroke N/D per period in bytes 48..59 (their reserved rule is off)
    def net(n, d, periodic=True):
        return dict(format_version=2, flags=1 if periodic else 0, reserved_48=struct.pack("<qI", n, d))

    for n, d, expected in ((360000, 1, OK), (-7, 3, OK), (2**31 - 1, 1, OK), (-(2**31) + 1, 1, OK),
                           (NET_MAX, 2**32 - 1, OK), (NET_MAX + 1, 2**32 - 1, "ECAM_E_NET_STROKE"),
                           (1, 2**32 - 1, OK), (-(2**32) + 1, 2**32 - 1, "ECAM_E_NET_STROKE"),
                           (360000, 0, "ECAM_E_NET_STROKE"), (720000, 2, "ECAM_E_NET_STROKE"),
                           (0, 5, "ECAM_E_NET_STROKE"), (2**31, 1, "ECAM_E_NET_STROKE"),
                           (-(2**31), 1, "ECAM_E_NET_STROKE"), (-(2**63), 1, "ECAM_E_NET_STROKE")):  # fmt: skip
        add(f"net{n}/{d}", expected if expected == OK else CODES[expected], table=zero_cubic, **net(n, d))
    add("net_not_periodic", CODES["ECAM_E_NET_STROKE"], table=zero_cubic, **net(1, 1, periodic=False))
    add("net0/1_version2", OK, table=zero_cubic, **net(0, 1))  # "none", written as version 2
    add("version2_reserved29", CODES["ECAM_E_RESERVED"], table=zero_cubic, reserved_29=b"\x01\x00\x00",
        **net(1, 1))  # fmt: skip
    add("version1_net_bytes", CODES["ECAM_E_RESERVED"], table=zero_cubic, reserved_48=struct.pack("<qI", 1, 1))
    # version 3: a net stroke whose ramp S = floor(N / (D M)) (M = 3000 here) is within +-(2^15 - 1)
    for n, d, expected in ((360000, 1, OK), (0, 1, "ECAM_E_RAMP"), (32767 * 3000, 1, OK),
                           (32768 * 3000, 1, "ECAM_E_RAMP"), (-32767 * 3000, 1, OK),
                           (-32767 * 3000 - 1, 1, "ECAM_E_RAMP"), (-1, 7, OK), (1, 1, OK),
                           (720000, 2, "ECAM_E_NET_STROKE")):  # fmt: skip
        add(f"ramp{n}/{d}", expected if expected == OK else CODES[expected], table=zero_cubic,
            **dict(net(n, d), format_version=3))
    add("ramp_not_periodic", CODES["ECAM_E_NET_STROKE"], table=zero_cubic,
        **dict(net(1, 1, periodic=False), format_version=3))
    # the overflow proof: one blob per rule, its payload pushed past exactly that bound
    out += proof_rule_set()
    out.append(("valid", good, OK))
    return out


def proof_rule_set() -> list:
    """(name, blob, expected) reaching each rule of the overflow proof, with both CRCs valid."""
    out = []

    def add(name, expected, **table):
        blob = cb.make_blob(cb.Table(**table))
        assert proof_status(blob) == CODES[expected], (name, proof_status(blob))
        out.append((name, blob, CODES[expected]))

    base = dict(degree=3, periodic=True, master_counts=3000, tau_bits=11, work_bits=20, slope_bits=20,
                curvature_bits=0, slope_preshift=0, position_bits=0)  # fmt: skip
    add("point_range", "ECAM_E_POINT_RANGE", **dict(base, work_bits=40, position_bits=0, slope_bits=40,
        slope_preshift=4, position=(2**22, 0, 0), slope=(0, 0, 0)))  # fmt: skip
    add("horner_range", "ECAM_E_HORNER_RANGE", **dict(base, work_bits=40, slope_bits=0, slope_preshift=4,
        position=(0, 0, 0), slope=(2**31 - 1, 0, 0)))  # fmt: skip
    # h = 1 (F = 0, tau always 0): no Horner product, so only the sums bound the coefficients
    h1 = dict(base, master_counts=2, tau_bits=0, work_bits=40, slope_bits=0, position=(0, 0, 0))
    add("sum_range", "ECAM_E_SUM_RANGE", **dict(h1, slope=(2**31 - 1, 0, 0)))
    add("position_range", "ECAM_E_POSITION_RANGE", **dict(base, position=(2**31 - 1, 0, 0), slope=(2**20, 0, 0),
        work_bits=0, slope_bits=0))  # fmt: skip
    add("slope_horner_range", "ECAM_E_SLOPE_HORNER_RANGE", **dict(h1, slope=(0, 2**21, 0)))  # q = 5 * 2^61
    add("slope_product", "ECAM_E_SLOPE_PRODUCT", **dict(base, tau_bits=30, work_bits=0, slope_bits=0,
        position=(0, 1000, 0), slope=(0, 0, 0)))  # fmt: skip
    add("slope_range", "ECAM_E_SLOPE_RANGE", **dict(base, work_bits=0, slope_bits=0, slope_preshift=27,
        position=(0, 1000, 0), slope=(0, 0, 0)))  # fmt: skip
    return out


def test_field_rules(cli, build_dir):
    _check_all(cli, build_dir, field_rule_set(), "fields")


def test_field_rules_sanitized(cli_asan, build_dir):
    _check_all(cli_asan, build_dir, field_rule_set(), "fields_asan", True)


def test_cli_usage_and_input_errors(cli, build_dir):
    table, blob, _, _ = case_data((1, False, "pow2"))
    path = write_blob(build_dir, "cli.ecam", blob)
    assert run_cli(cli, []).returncode == 2
    assert run_cli(cli, ["--check"]).returncode == 2
    assert run_cli(cli, ["--check", build_dir / "missing.ecam"]).returncode == 2
    proc = run_cli(cli, ["--check", path])
    assert (proc.returncode, proc.stdout) == (0, b"ok\n")
    bad = write_blob(build_dir, "bad.ecam", blob[:10])
    proc = run_cli(cli, [bad], b"0\n")
    assert (proc.returncode, proc.stdout) == (1, b"error -1 ECAM_E_SHORT\n")
    for text in (b"12x\n", b"9223372036854775808\n", b"-9223372036854775809\n", b"1.5\n"):
        assert run_cli(cli, [path], text).returncode == 2, text
    proc = run_cli(cli, [path], b" -1 \r\n\n5")  # padding, CRLF, a blank line, no final newline
    assert proc.returncode == 0
    assert proc.stdout.decode().split() == [str(v) for v in (
        *cb.reference_lookup(table, -1), *cb.reference_lookup(table, 5))]  # fmt: skip


# --------------------------------------------------------------------------------------------
# Golden vectors (FORMAT.md "Worked check") and the shipped tables
# --------------------------------------------------------------------------------------------

GOLDEN = sorted(p for p in (FIRMWARE / "vectors").glob("*.csv") if p.with_suffix(".bin").exists())


def table_from_blob(blob: bytes) -> cb.Table:
    """Parse a blob back into a c_blobs.Table (and prove the writer reproduces it exactly)."""
    names = [name for name, _ in cb.HEADER_FIELDS]
    v = dict(zip(names, cb.HEADER_STRUCT.unpack(blob[:60])))
    n, degree = v["points"], v["degree"]
    arrays = [struct.unpack_from(f"<{n}i", blob, 64 + 4 * n * k) for k in range(3)[: (degree + 1) // 2]]
    table = cb.Table(
        degree=degree, periodic=bool(v["flags"] & 1), master_counts=v["master_counts"],
        tau_bits=v["tau_bits"], work_bits=v["work_bits"], slope_bits=v["slope_bits"],
        curvature_bits=v["curvature_bits"], slope_preshift=v["slope_preshift"],
        position_bits=v["position_bits"], position=arrays[0],
        slope=arrays[1] if degree >= 3 else (), curvature=arrays[2] if degree == 5 else (),
        **(dict(zip(("net_num", "net_den"), struct.unpack("<qI", v["reserved_48"])))
           if v["format_version"] >= 2 else {}), ramp=v["format_version"] == 3,
    )  # fmt: skip
    assert cb.make_blob(table) == blob
    return table


@pytest.mark.parametrize("csv", GOLDEN, ids=lambda p: p.stem)
@pytest.mark.parametrize("sanitized", (False, True), ids=("strict", "asan"))
def test_golden_vectors(request, csv, sanitized):
    cli = request.getfixturevalue("cli_asan" if sanitized else "cli")
    rows = np.loadtxt(csv, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    queries, expected = rows[:, 0], rows[:, 1:]
    wrapped = np.stack([cb.int32_wrap(expected[:, 0]), expected[:, 1]], 1)  # a net stroke passes int32
    assert_same(queries, c_lookups(cli, csv.with_suffix(".bin"), queries, sanitized), wrapped,
                f"C runtime vs {csv.name}")  # fmt: skip
    if not sanitized:
        table = table_from_blob(csv.with_suffix(".bin").read_bytes())
        ours = np.array([cb.reference_lookup(table, m) for m in queries.tolist()], dtype=np.int64)
        assert_same(queries, ours, expected, f"tests/c_blobs.py vs {csv.name}")


def test_shipped_tables_load(cli):
    blobs = sorted((FIRMWARE / "tables").glob("*.bin")) + [p.with_suffix(".bin") for p in GOLDEN]
    if not blobs:
        pytest.skip("no generated tables in firmware_tables/ yet")
    assert c_checks(cli, blobs) == [OK] * len(blobs)


def test_generated_headers_build_with_runtime(cli, build_dir):
    """Each generated tables/NAME.h compiles strictly next to the runtime, and its NAME_blob
    loads and looks up like the matching NAME.bin."""
    headers = [h for h in sorted((FIRMWARE / "tables").glob("*.h")) if h.with_suffix(".bin").exists()]
    if not headers:
        pytest.skip("no generated tables in firmware_tables/tables/ yet")
    for header in headers:
        ident = "".join(c if c.isalnum() else "_" for c in header.stem)
        if f"{ident}_blob[" not in header.read_text():
            pytest.fail(f"{header.name} has no {ident}_blob[] array")
        main = build_dir / f"header_{ident}.c"
        main.write_text(HEADER_PROGRAM.replace("NAME", ident).replace("HEADER", header.name))
        exe = _compile(build_dir / f"header_{ident}", [main, *RUNTIME],
                       STRICT_FLAGS + ["-pedantic", "-I", str(header.parent)])  # fmt: skip
        table = table_from_blob(header.with_suffix(".bin").read_bytes())
        queries = np.array(cb.edge_queries(table), dtype=np.int64)
        proc = run_cli(exe, [], ("\n".join(map(str, queries.tolist())) + "\n").encode())
        assert proc.returncode == 0, proc.stdout + proc.stderr
        got = np.array(proc.stdout.split(), dtype=np.int64).reshape(-1, 2)
        expected = c_lookups(cli, header.with_suffix(".bin"), queries)
        assert_same(queries, got, expected, f"{header.name} vs {header.with_suffix('.bin').name}")


HEADER_PROGRAM = r"""
#include <stdio.h>
#include <inttypes.h>
#include "ecam_table.h"
#include "HEADER"

int main(void)
{
    ecam_table t;
    long long m;
    int rc = ecam_table_init(&t, NAME_blob, sizeof NAME_blob);

    if (rc != ECAM_OK) {
        printf("error %d %s\n", rc, ecam_status_name(rc));
        return 1;
    }
    while (scanf("%lld", &m) == 1) {
        int32_t p, s;
        ecam_table_lookup(&t, (int64_t)m, &p, &s);
        printf("%" PRId32 " %" PRId32 "\n", p, s);
    }
    return 0;
}
"""


# --------------------------------------------------------------------------------------------
# Cross-check with the real Python implementation
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", MAIN_CASES + EDGE_CASES, ids=_case_id)
def test_ecam_camtable_agrees(cli, build_dir, case):
    table, blob, queries, expected = case_data(case)
    cam = CamTable.from_bytes(blob)
    positions, slopes = cam.lookup(queries), cam.slope(queries)
    got = np.stack([np.asarray(positions, dtype=np.int64), np.asarray(slopes, dtype=np.int64)], 1)
    assert_same(queries, got, expected, "ecam.CamTable " + _case_id(case))


# --------------------------------------------------------------------------------------------
# Every arithmetic path, every build: warnings, and the bits of the paths other hosts take
# --------------------------------------------------------------------------------------------

# The warning set the runtime promises to be clean under (README, FORMAT.md).
RUNTIME_WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Wconversion", "-Wsign-conversion", "-Wcast-align",
                    "-pedantic", "-Werror"]  # fmt: skip
# The arithmetic paths: 64-bit cores (one multiply + shift per Horner step, __int128 wrap), the
# portable wrap without __int128, and the 32-bit cores' path (high-word products, 32x32 scales).
ARITHMETIC_PATHS = {"word64": [], "no_int128": ["-DECAM_NO_INT128"], "word32": ["-DECAM_WORD_BITS=32"]}


@pytest.mark.parametrize("compiler", ["cc", "clang"])
@pytest.mark.parametrize("opt", ["-O0", "-O2", "-Os"])
@pytest.mark.parametrize("path", list(ARITHMETIC_PATHS))
def test_runtime_compiles_without_warnings(build_dir, path, opt, compiler):
    """The promised warning set, with the system compiler and with clang (Debian: clang) where
    installed, on every arithmetic path and optimisation level."""
    cc = _compiler() if compiler == "cc" else shutil.which(compiler)
    if cc is None:
        pytest.skip(f"{compiler} not found (Debian: apt-get install {'gcc' if compiler == 'cc' else compiler})")
    for source in ("ecam_table.c", "ecam_minimal.c", "ecam_target.c", "ecam_host_io.c"):
        cmd = [cc, *RUNTIME_WARNINGS, opt, *ARITHMETIC_PATHS[path], "-c", "-o", str(build_dir / "w.o"),
               str(FIRMWARE / source)]  # fmt: skip
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0 and proc.stderr == "", f"{' '.join(cmd)}\n{proc.stderr}"


@pytest.fixture(scope="session")
def path_clis(build_dir) -> dict:
    return {name: _compile(build_dir / f"ecam_cli_{name}", CLI_SOURCES, STRICT_FLAGS + flags)
            for name, flags in ARITHMETIC_PATHS.items() if flags}  # fmt: skip


@pytest.mark.parametrize("path", [p for p, flags in ARITHMETIC_PATHS.items() if flags])
def test_other_arithmetic_paths_match_reference(path_clis, build_dir, path):
    """The paths a 32-bit core or a compiler without __int128 takes, run here bit for bit."""
    cli = path_clis[path]
    for case in MAIN_CASES + EDGE_CASES:
        table, blob, queries, expected = case_data(case)
        n = min(60_000, queries.size)
        blob_path = write_blob(build_dir, f"{path}-{_case_id(case)}.ecam", blob)
        assert_same(queries[:n], c_lookups(cli, blob_path, queries[:n]), expected[:n], f"{path} {_case_id(case)}")
    for csv in GOLDEN:
        rows = np.loadtxt(csv, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
        wrapped = np.stack([cb.int32_wrap(rows[:, 1]), rows[:, 2]], 1)  # a net stroke passes int32
        assert_same(rows[:, 0], c_lookups(cli, csv.with_suffix(".bin"), rows[:, 0]), wrapped, f"{path} {csv.name}")


# --------------------------------------------------------------------------------------------
# Switching tables while an interrupt reads (ecam_table_pair)
# --------------------------------------------------------------------------------------------

PAIR_HARNESS = r"""
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include "ecam_table.h"

#define QUERIES 64
static ecam_table_pair pair;
static int64_t masters[QUERIES];
static int32_t expected[2][QUERIES];
static volatile sig_atomic_t ticks, seen_a, seen_b, seen_invalid, mixed, garbage;

/* The "interrupt": one acquire, then lookups in that table only. Each invocation must see table
 * A, table B or (before the first load) a table that is not ready; never a mix, never garbage. */
static void on_tick(int sig)
{
    const ecam_table *t = ecam_pair_acquire(&pair);
    int a = 0, b = 0, invalid = 0, k;

    (void)sig;
    for (k = 0; k < QUERIES; k++) {
        const int32_t p = ecam_table_position(t, masters[k]);
        if (p == expected[0][k] && p != expected[1][k]) a++;
        else if (p == expected[1][k] && p != expected[0][k]) b++;
        else if (p == ECAM_INVALID) invalid++;
        else if (p != expected[0][k]) garbage++;
    }
    if ((a > 0) + (b > 0) + (invalid > 0) > 1) mixed++;
    if (a) seen_a++;
    if (b) seen_b++;
    if (invalid) seen_invalid++;
    ticks++;
}

static unsigned char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    unsigned char *data = malloc(1 << 20);
    if (f == NULL || data == NULL) exit(3);
    *len = fread(data, 1, 1 << 20, f);
    fclose(f);
    return data;
}

int main(int argc, char **argv)
{
    size_t len_a, len_b, len_bad;
    unsigned char *blob_a = slurp(argv[1], &len_a), *blob_b = slurp(argv[2], &len_b);
    unsigned char *bad = slurp(argv[1], &len_bad);
    ecam_table ta, tb;
    struct itimerval timer;
    struct sigaction action;
    long loads = 0, busy = 0, rejected = 0, k;
    int rc;

    if (argc != 4) return 2;
    bad[70] ^= 1u; /* payload CRC mismatch: must be rejected without touching the active table */
    if (ecam_table_init(&ta, blob_a, len_a) || ecam_table_init(&tb, blob_b, len_b)) return 4;
    for (k = 0; k < QUERIES; k++) {
        masters[k] = (int64_t)(k * 7919) - 100000;
        expected[0][k] = ecam_table_position(&ta, masters[k]);
        expected[1][k] = ecam_table_position(&tb, masters[k]);
    }
    ecam_pair_init(&pair);
    /* Without interrupts: the protocol's states, deterministically. */
    printf("before_load=%d\n", (int)ecam_table_position(ecam_pair_acquire(&pair), 0));
    printf("first_load=%d\n", ecam_pair_load(&pair, blob_a, len_a));
    printf("idle_before_interrupt=%d\n", ecam_pair_idle(&pair));
    printf("second_load_busy=%d\n", ecam_pair_load(&pair, blob_b, len_b));
    printf("acquired_a=%d\n", ecam_table_position(ecam_pair_acquire(&pair), masters[5]) == expected[0][5]);
    printf("idle=%d\n", ecam_pair_idle(&pair));
    printf("bad_load=%d\n", ecam_pair_load(&pair, bad, len_bad));
    printf("still_a=%d\n", ecam_table_position(ecam_pair_acquire(&pair), masters[5]) == expected[0][5]);
    /* With a real asynchronous interrupt: a 20 us timer signal, while loads alternate. */
    memset(&action, 0, sizeof action);
    action.sa_handler = on_tick;
    sigaction(SIGALRM, &action, NULL);
    timer.it_interval.tv_sec = 0;
    timer.it_interval.tv_usec = 20;
    timer.it_value = timer.it_interval;
    setitimer(ITIMER_REAL, &timer, NULL);
    while (ticks < atol(argv[3])) {
        rc = ecam_pair_load(&pair, (loads & 1) ? blob_a : blob_b, (loads & 1) ? len_a : len_b);
        if (rc == ECAM_OK) loads++;
        else if (rc == ECAM_E_BUSY) busy++;
        else return 5;
        if (ecam_pair_load(&pair, bad, len_bad) != ECAM_E_PAYLOAD_CRC) return 6;
        rejected++;
    }
    timer.it_value.tv_usec = 0;
    timer.it_interval.tv_usec = 0;
    setitimer(ITIMER_REAL, &timer, NULL);
    printf("ticks=%ld loads=%ld busy=%ld rejected=%ld seen_a=%ld seen_b=%ld seen_invalid=%ld mixed=%ld garbage=%ld\n",
           (long)ticks, loads, busy, rejected, (long)seen_a, (long)seen_b, (long)seen_invalid, (long)mixed,
           (long)garbage);
    return 0;
}
"""


def test_table_switch_while_an_interrupt_reads(build_dir):
    """ecam_table_pair: the main loop keeps loading tables A and B (and a corrupt blob) while a
    20 us timer signal (a real asynchronous interrupt of the main loop) looks up 64 masters per
    invocation. Every invocation sees A or B entirely; a rejected blob never disturbs the table
    in use; the spare is only rewritten after the interrupt has moved to the new table."""
    if os.name != "posix":
        pytest.skip("needs POSIX timer signals")
    source = build_dir / "pair_harness.c"
    source.write_text(PAIR_HARNESS)
    exe = _compile(build_dir / "pair_harness", [source, *RUNTIME], ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"])
    rng = np.random.default_rng(91)
    a = cb.random_table(rng, 5, True, 360_000, 60)
    b = cb.random_table(rng, 5, True, 360_000, 60)
    path_a, path_b = write_blob(build_dir, "pair_a.ecam", cb.make_blob(a)), write_blob(build_dir, "pair_b.ecam", cb.make_blob(b))
    proc = subprocess.run([str(exe), str(path_a), str(path_b), "4000"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    head = dict(line.split("=", 1) for line in proc.stdout.splitlines() if line.count("=") == 1)
    assert head["before_load"] == str(ECAM_INVALID)
    assert head["first_load"] == "0" and head["idle_before_interrupt"] == "0"
    assert head["second_load_busy"] == str(CODES["ECAM_E_BUSY"])
    assert head["acquired_a"] == "1" and head["idle"] == "1"
    assert head["bad_load"] == str(E_PAYLOAD_CRC) and head["still_a"] == "1"
    stats = dict(item.split("=") for item in proc.stdout.splitlines()[-1].split())
    stats = {k: int(v) for k, v in stats.items()}
    assert stats["mixed"] == 0 and stats["garbage"] == 0, stats
    assert stats["seen_invalid"] == 0, stats  # a table was active before the timer started
    assert stats["ticks"] >= 4000 and stats["loads"] >= 100 and stats["seen_a"] > 0 and stats["seen_b"] > 0, stats


# --------------------------------------------------------------------------------------------
# Net stroke (format version 2): step 7 on every arithmetic path
# --------------------------------------------------------------------------------------------

# N/D per period: reduced, |N| < D 2^31; the largest magnitudes the rule allows included
NET_MAX = 9223372034707292159  # the largest N < (2^32 - 1) 2^31 with gcd(N, 2^32 - 1) = 1
NET_STROKES = [(360000, 1), (-7, 3), (1, 2**32 - 1), (-(2**32) + 2, 2**32 - 1), (2**31 - 1, 1),
               (-(2**31) + 1, 1), (2**62 + 7, 2**32 - 1), (NET_MAX, 2**32 - 1), (-NET_MAX, 2**32 - 1),
               (90000009, 250)]  # fmt: skip


def net_stroke_cases() -> list:
    """(name, blob, queries, expected (n, 2) as the C runtime returns it: int32 positions)."""
    import dataclasses

    rng = np.random.default_rng(934)
    out = []
    # every degree with a whole stroke (D = 1) and h = 6000 too (the linear kernel's own step 7)
    cases = [(num, den, (1, 3, 5)[k % 3], ((2**20, 64), (360_000, 60), (3, 1), (2**31, 2))[k % 4], False)
             for k, (num, den) in enumerate(NET_STROKES)]
    cases += [(-1234567, 1, degree, (360_000, 60), False) for degree in (1, 3, 5)]
    # version 3 (step 8): the data relative to the ramp S m, S = floor(N / (D M)) up to its edges
    ramps = [(64 * 2**20 + 12345, 1, 5, (2**20, 64)), (-(5 * 360_000) + 7, 3, 3, (360_000, 60)),
             (1024 * 2**20, 1, 1, (2**20, 64)), (32767 * 3000 + 1, 1, 5, (3000, 2)), (-32767 * 3000, 1, 3, (3000, 3)),
             (1080001, 3, 1, (360_000, 60))]  # fmt: skip
    cases += [(num, den, degree, shape, True) for num, den, degree, shape in ramps]
    for num, den, degree, (M, N), ramp in cases:
        # a ramp at its edge leaves the data's slope less than a count per master count of int32:
        # data of zeros there, the ramp and the net term alone
        edge = ramp and abs(num) // (den * M) > 2**14
        table = dataclasses.replace(zero_table(degree, M, N) if edge else cb.random_table(rng, degree, True, M, N),
                                    net_num=num, net_den=den, ramp=ramp)
        assert cb.proof_failure(table) is None, (num, den, degree)
        queries = cb.random_queries(rng, table, 4000)
        expected = np.array([cb.reference_lookup(table, m) for m in queries.tolist()], dtype=np.int64)
        cam = CamTable.from_bytes(cb.make_blob(table))
        python = np.stack([np.asarray(cam.lookup(queries), dtype=np.int64), np.asarray(cam.slope(queries))], 1)
        assert_same(queries, python, expected, f"CamTable vs tests/c_blobs.py, net {num}/{den}")
        expected[:, 0] = cb.int32_wrap(expected[:, 0])
        out.append((f"{'ramp' if table.ramp else 'net'}{num}/{den}-deg{degree}", cb.make_blob(table), queries, expected))
    return out


@pytest.mark.parametrize("path", list(ARITHMETIC_PATHS))
def test_net_stroke_lookups_on_every_path(cli, path_clis, build_dir, path):
    """Version-2 tables: the position adds floor((k N + floor(D/2)) / D) for the k whole periods
    passed, and the C runtime returns its int32 wrap; N/D at the edges of their rules."""
    exe = cli if path == "word64" else path_clis[path]
    for name, blob, queries, expected in net_stroke_cases():
        blob_path = write_blob(build_dir, f"{path}-{name.replace('/', '_')}.ecam", blob)
        assert_same(queries, c_lookups(exe, blob_path, queries), expected, f"{path} {name}")
