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
CLI_SOURCES = [FIRMWARE / "ecam_cli.c", FIRMWARE / "ecam_table.c"]
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
SANITIZE_FLAGS = [
    "-std=c99", "-Wall", "-Wextra", "-Werror", "-O1", "-g", "-fno-omit-frame-pointer",
    "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
]  # fmt: skip
SANITIZER_ENV = {
    "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0:exitcode=99",
    "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1:exitcode=98",
}

OK, E_SHORT, E_MAGIC, E_VERSION, E_HEADER_SIZE, E_HEADER_CRC = 0, -1, -2, -3, -4, -5
E_FIELD, E_LENGTH, E_PAYLOAD_CRC, E_NULL = -6, -7, -8, -9
STATUS_NAMES = {
    OK: "ECAM_OK", E_SHORT: "ECAM_E_SHORT", E_MAGIC: "ECAM_E_MAGIC", E_VERSION: "ECAM_E_VERSION",
    E_HEADER_SIZE: "ECAM_E_HEADER_SIZE", E_HEADER_CRC: "ECAM_E_HEADER_CRC",
    E_FIELD: "ECAM_E_FIELD", E_LENGTH: "ECAM_E_LENGTH", E_PAYLOAD_CRC: "ECAM_E_PAYLOAD_CRC",
    E_NULL: "ECAM_E_NULL",
}  # fmt: skip

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
        assert head["failed_table_lookup"] == "0 0 0 0"
        assert head["null_table_lookup"] == "0 0 0 0"
        assert head["misaligned_init"] == "0"
        for code, name in STATUS_NAMES.items():
            assert head[f"name{code}"] == name
        assert head["name1"] == head["name-100"] == "ECAM_E_UNKNOWN"


API_HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <inttypes.h>
#include "ecam_table.h"

int main(int argc, char **argv)
{
    static uint8_t storage[1 << 16];
    uint8_t *blob = storage + 1; /* deliberately misaligned */
    ecam_table t, failed;
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
    ecam_table_init(&failed, blob, len - 1);
    ecam_table_lookup(&failed, 12345, &p, &s);
    printf("failed_table_lookup=%d %d %d %d\n", (int)p, (int)s,
           (int)ecam_table_position(&failed, 7), (int)ecam_table_slope(&failed, 7));
    ecam_table_lookup(NULL, 12345, &p, &s);
    printf("null_table_lookup=%d %d %d %d\n", (int)p, (int)s,
           (int)ecam_table_position(NULL, 7), (int)ecam_table_slope(NULL, 7));
    for (code = -10; code <= 1; code++) printf("name%d=%s\n", code, ecam_status_name(code));
    printf("name-100=%s\n", ecam_status_name(-100));
    printf("misaligned_init=%d\n", ecam_table_init(&t, blob, len));
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


def field_rule_set() -> list:
    """(name, blob, expected) for each rule of FORMAT.md, with a valid header CRC, plus valid
    blobs at the edges of each rule as positive controls."""
    linear = small_table(1)  # h = 1500, not a power of two
    cubic = small_table(3)
    quintic = small_table(5)
    pow2 = cb.random_table(np.random.default_rng(50), 3, True, 2**12, 4)  # h = 1024
    h = cubic.step_counts
    out = []

    def add(name, expected, table=cubic, **fields):
        out.append((name, cb.make_blob(table, **fields), expected))

    # The envelope checks, in FORMAT.md order.
    add("magic", E_MAGIC, magic=b"ECAm")
    for version in (0, 2, 0x0101):
        add(f"version{version}", E_VERSION, format_version=version)
    for size in (0, 63, 65, 128):
        add(f"header_bytes{size}", E_HEADER_SIZE, header_bytes=size)
    good = cb.make_blob(cubic)
    out.append(("header_crc", cb.patch(good, 60, struct.pack("<I", 0), False), E_HEADER_CRC))
    # degree and flags
    for degree in (0, 2, 4, 6, 7, 255):
        add(f"degree{degree}", E_FIELD, degree=degree)
    add("degree3_as_5", E_FIELD, degree=5)  # payload_bytes no longer points * 12
    for flags in (2, 3, 0x80, 0xFE):
        add(f"flags{flags:#x}", E_FIELD, flags=flags)
    add("flags0", OK, flags=0)
    # step_shift and tau_bits
    for shift in (-2, 0, 10, 11, 127, -128):
        add(f"step_shift{shift}", E_FIELD, step_shift=shift)
    for shift in (-1, 9, 11):
        add(f"pow2_step_shift{shift}", E_FIELD, table=pow2, step_shift=shift)
    lowest = cb.ceil_log2(h)
    add("tau_bits_below_log2h", E_FIELD, tau_bits=lowest - 1, tau_recip=_recip(h, lowest - 1))
    for F in (lowest, 30):
        for P in (0, 16 + F + cubic.work_bits):
            if 16 + F + cubic.work_bits - P <= 63 and F + cubic.work_bits <= 63:
                add(f"tau_bits{F}_P{P}", OK, tau_bits=F, tau_recip=_recip(h, F), slope_preshift=P)
    add("tau_bits31", E_FIELD, tau_bits=31, tau_recip=_recip(h, 31))
    add("pow2_tau_bits_k+1", E_FIELD, table=pow2, tau_bits=11, tau_recip=_recip(1024, 11))
    add("pow2_tau_bits_k-1", E_FIELD, table=pow2, tau_bits=9, tau_recip=_recip(1024, 9))
    # Qy, W, Qa, Qb; P is set so that 16 + F + W - P = 0 stays valid whatever W is tried
    F = cubic.tau_bits

    def bits(qy, w, **more):
        return dict(position_bits=qy, work_bits=w, slope_bits=0, slope_preshift=16 + F + w, **more)

    add("work_bits41", E_FIELD, **bits(0, 41))
    add("work_bits40", OK, **bits(0, 40))
    add("position_bits31", E_FIELD, **bits(31, 40))
    add("position_bits30", OK, **bits(30, 40))
    add("work_bits_below_Qy", E_FIELD, **bits(11, 10))
    add("work_bits_eq_Qy", OK, **bits(10, 10))
    add("slope_bits_gt_W", E_FIELD, **dict(bits(5, 20), slope_bits=21))
    add("slope_bits_eq_W", OK, **dict(bits(5, 20), slope_bits=20))
    add("cubic_curvature_bits1", E_FIELD, curvature_bits=1)
    add("curvature_bits_gt_W", E_FIELD, table=quintic, **bits(0, 20, curvature_bits=21))
    add("quintic_bits_eq_W", OK, table=quintic, **dict(bits(20, 20, curvature_bits=20),
                                                       slope_bits=20))  # fmt: skip
    lf = linear.tau_bits
    for qy, w, expected in ((5, 5, OK), (5, 6, E_FIELD), (6, 5, E_FIELD), (0, 1, E_FIELD)):
        add(f"linear_Qy{qy}_W{w}", expected, table=linear, position_bits=qy, work_bits=w,
            slope_preshift=16 + lf + w)  # fmt: skip
    add("linear_slope_bits1", E_FIELD, table=linear, slope_bits=1)
    add("linear_curvature_bits1", E_FIELD, table=linear, curvature_bits=1)
    # P: 16 + F + W - P in 0..63; P itself may exceed 63
    W = cubic.work_bits
    add("P_too_large", E_FIELD, slope_preshift=16 + F + W + 1)
    add("P_max", OK, slope_preshift=16 + F + W)
    f30 = dict(tau_bits=30, tau_recip=_recip(h, 30), work_bits=40, slope_bits=0)  # 16+F+W = 86
    for P, expected in ((22, E_FIELD), (23, OK), (64, OK), (86, OK), (87, E_FIELD)):
        add(f"F30_W40_P{P}", expected, slope_preshift=P, **f30)
    big = dict(tau_bits=30, tau_recip=_recip(h, 30), work_bits=20, slope_bits=0)  # 16+F+W = 66
    add("P_too_small", E_FIELD, slope_preshift=2, **dict(big, position_bits=0))
    add("P_min", OK, slope_preshift=3, **dict(big, position_bits=0))
    # points, M, h
    add("points1", E_FIELD, points=1)
    add("points4", E_FIELD, points=4)
    add("master_counts_off", E_FIELD, master_counts=3001)
    add("step_counts_off", E_FIELD, step_counts=1501, tau_recip=_recip(1501, F))
    add("step_counts0", E_FIELD, step_counts=0)
    for name, table, expected in (
        ("master_counts1", linear_table(1, 0, (0, 0)), E_FIELD),  # N * h == M holds
        ("master_counts2", linear_table(2, 0, (0, 0, 0)), OK),
        ("master_counts2^31", linear_table(2**31, 30, (0, 0, 0)), OK),
        ("master_counts3*2^30", linear_table(3 * 2**30, 30, (0, 0, 0, 0)), E_FIELD),
        ("step_counts2^31", linear_table(2**31, 31, (0, 0)), E_FIELD),  # h > 2^30
    ):
        out.append((name, cb.make_blob(table), expected))
    # payload_bytes that only matches modulo 2^32: points * 12 for points = 2^30 + 1
    values = dict(quintic.header_values(), points=2**30 + 1, master_counts=2**31,
                  step_counts=2, step_shift=1, tau_bits=1, tau_recip=2**32, slope_preshift=0,
                  payload_bytes=((2**30 + 1) * 12) % 2**32)  # fmt: skip
    payload = bytes(values["payload_bytes"])
    values["payload_crc32"] = zlib.crc32(payload)
    out.append(("payload_bytes_mod_2^32", cb.pack_blob(values, payload), E_FIELD))
    # reserved
    for k in range(3):
        add(f"reserved29+{k}", E_FIELD, reserved_29=bytes(k) + b"\x80" + bytes(2 - k))
    for k in range(12):
        add(f"reserved48+{k}", E_FIELD, reserved_48=bytes(k) + b"\x01" + bytes(11 - k))
    # tau_recip
    R = cubic.tau_recip
    for delta in (-1, 1, 2**32):
        add(f"tau_recip{delta:+d}", E_FIELD, tau_recip=R + delta)
    for value in (0, 2**64 - 1, 2**63):
        add(f"tau_recip={value:#x}", E_FIELD, tau_recip=value)
    add("pow2_tau_recip+1", E_FIELD, table=pow2, tau_recip=2**32 + 1)
    add("pow2_tau_recip-1", E_FIELD, table=pow2, tau_recip=2**32 - 1)
    # payload_bytes vs length vs payload CRC
    n_bytes = len(cubic.payload())
    for delta in (-4, -1, 1, 4):  # total length kept consistent, so only the field rule fails
        blob = cb.make_blob(cubic, payload_bytes=n_bytes + delta)
        blob = blob[: 64 + n_bytes + delta] + bytes(max(delta, 0))
        out.append((f"payload_bytes{delta:+d}", blob, E_FIELD))
    add("length_only", E_LENGTH, payload_bytes=n_bytes)  # control: unchanged header
    out[-1] = ("length_only", good + b"\x00\x00\x00\x00", E_LENGTH)
    add("payload_crc", E_PAYLOAD_CRC, payload_crc32=cubic.header_values()["payload_crc32"] ^ 1)
    out.append(("valid", good, OK))
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
    )  # fmt: skip
    assert cb.make_blob(table) == blob
    return table


@pytest.mark.parametrize("csv", GOLDEN, ids=lambda p: p.stem)
@pytest.mark.parametrize("sanitized", (False, True), ids=("strict", "asan"))
def test_golden_vectors(request, csv, sanitized):
    cli = request.getfixturevalue("cli_asan" if sanitized else "cli")
    rows = np.loadtxt(csv, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    queries, expected = rows[:, 0], rows[:, 1:]
    assert_same(queries, c_lookups(cli, csv.with_suffix(".bin"), queries, sanitized), expected,
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
