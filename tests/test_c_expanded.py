"""The expanded form (issue 27 item 2, FORMAT.md "Expanded form"): ecam_poly_init precomputes each
interval's polynomial into the caller's buffer, and ecam_poly_position looks up through it, bit for
bit the same as ecam_table_position (and so as the Python lookup) for every int64 master, on every
arithmetic path of this host: 64-bit words (with and without __int128) and 32-bit words, where a
table compiled with ``horner_bits=32`` runs the narrow (32x32) kernels."""

from __future__ import annotations

import dataclasses
import functools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ecam import CamTable, compile_table, load_cam
from ecam.table import narrow_horner

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import c_blobs as cb  # noqa: E402
from test_c_runtime import SANITIZE_FLAGS, _compile  # noqa: E402

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware_tables"
TARGET_SOURCES = [FIRMWARE / name for name in ("ecam_target.c", "ecam_host_io.c", "ecam_table.c", "ecam_minimal.c")]
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wconversion", "-Wsign-conversion", "-pedantic", "-Werror", "-O2"]
# "32-divide-sanitized": the path of a 32-bit core with a divide instruction (the Cortex-M3/M4's,
# where ECAM_HW_DIVIDE is 1 by itself), which wraps a table with h = 2^k by two 32-bit remainders
# (ecam_poly_fold) and every other by the Barrett reduction of "32", sanitized (a signed
# division's overflow would be reported).
PATHS = {"64": [], "64-no-int128": ["-DECAM_NO_INT128"], "32": ["-DECAM_WORD_BITS=32"],
         "32-divide-sanitized": ["-DECAM_WORD_BITS=32", "-DECAM_HW_DIVIDE=1", *SANITIZE_FLAGS[4:]]}  # -O1 -g ...


@pytest.fixture(scope="module")
def drivers(tmp_path_factory):
    directory = tmp_path_factory.mktemp("expanded")
    return {name: _compile(directory / f"ecam_target_{name}", TARGET_SOURCES, [*STRICT, *flags])
            for name, flags in PATHS.items()}


def narrow_tables() -> list:
    """Tables compiled for the narrow kernels: every kind, a step of 2^k and not, a clamp, and
    net strokes of a whole and of a fractional count per period."""
    drrd = load_cam(ROOT / "firmware_tables" / "cams" / "combination_drrd.toml")
    knife = load_cam(ROOT / "firmware_tables" / "cams" / "rotary_knife.toml")
    low, high = drrd.slave_range
    out = []
    for kind in ("linear", "cubic", "quintic"):
        for points in (65, 97):
            out.append((f"drrd-{kind}-{points}", compile_table(drrd, interp=kind, points=points, master_counts=36864 * 2,
                                                               slave_counts_per_unit=2**20 / (high - low),
                                                               horner_bits=32, certify=False)))
        out.append((f"knife-{kind}", compile_table(knife, interp=kind, points=61, horner_bits=32, certify=False)))
        out.append((f"knife-frac-{kind}", compile_table(knife, interp=kind, points=61, horner_bits=32, certify=False,
                                                        slave_counts_per_unit=1000.0001)))
    return out


def mask_tables() -> list:
    """Periods of M = 2^j master counts (the mask kernels): without and with a whole net stroke,
    at the ends of j (M = 2 and 2^31), in 32-bit and 64-bit words; a fractional net stroke and a
    clamp keep the reduction."""
    drrd = load_cam(ROOT / "firmware_tables" / "cams" / "combination_drrd.toml")
    knife = load_cam(ROOT / "firmware_tables" / "cams" / "rotary_knife.toml")
    out = []
    for kind in ("linear", "cubic", "quintic"):
        for bits in (32, 64):
            out.append((f"mask-knife-{kind}-{bits}", compile_table(knife, interp=kind, points=17, master_counts=2**16,
                                                                   horner_bits=bits, certify=False)))
            out.append((f"mask-drrd-{kind}-{bits}", compile_table(drrd, interp=kind, points=65, master_counts=2**16,
                                                                  horner_bits=bits, certify=False)))
        out.append((f"mask-knife-2^31-{kind}", compile_table(knife, interp=kind, points=65, master_counts=2**31,
                                                             certify=False)))
        out.append((f"mask-drrd-2-{kind}", compile_table(drrd, interp=kind, points=3, master_counts=2,
                                                         slave_counts_per_unit=1e-3, certify=False)))
        out.append((f"mask-knife-frac-{kind}", compile_table(knife, interp=kind, points=17, master_counts=2**16,
                                                             slave_counts_per_unit=1000.0001, certify=False)))
        # format version 3 (step 8): the mask kernels with the ramp (M = 2^20), and the ramp's own
        # kernel in front of the others (M = 3 x 2^19, a fractional net stroke)
        for bits in (32, 64):
            out.append((f"ramp-drum-{kind}-{bits}", compile_table(knife, interp=kind, points=65, master_counts=2**20,
                                                                  slave_counts_per_unit=2**26 / 360,
                                                                  horner_bits=bits, certify=False)))
        out.append((f"ramp-drum-3x2^19-{kind}", compile_table(knife, interp=kind, points=97, master_counts=3 * 2**19,
                                                              slave_counts_per_unit=2**30 / 360, horner_bits=32,
                                                              certify=False)))
        out.append((f"ramp-drum-frac-{kind}", compile_table(knife, interp=kind, points=65, master_counts=2**20,
                                                            slave_counts_per_unit=2**26 / 360 + 0.37, certify=False)))
    assert all(table.format_version == 3 for name, table in out if name.startswith("ramp"))
    return out


def fold_tables(rng) -> list:
    """A step of h = 2^k and a period M = N 2^k that is not a power of two (the wrap of
    ecam_poly_fold where the core divides): the seed cam at M = 9 x 2^13 in 32-bit and 64-bit
    words; random tables at the fold's bound, (N - 1)(2N - 1) + 2^(32-k) <= 2^32 (N = 32767, k = 1:
    the largest odd N it takes at k = 1), just past it (N = 32769: the Barrett wrap), at k = 28
    and k = 29 (N = 3: k = 29 is the largest step of a fold, M <= 2^31) and at N = 2310 = 2 x 3 x 5 x 7 x 11 (k = 10), and a clamp (no wrap). N = 32769's
    c = 2^31 mod N is 2, so a fold there would still be exact; N = 36829 (k = 1, c = 21487) is past
    the bound with a sum that does pass 2^32 (fold_extremes), so a looser condition in init fails."""
    drrd = load_cam(ROOT / "firmware_tables" / "cams" / "combination_drrd.toml")
    low, high = drrd.slave_range
    out = []
    for kind in ("linear", "cubic", "quintic"):
        for bits in (32, 64):
            out.append((f"fold-drrd-{kind}-{bits}", compile_table(drrd, interp=kind, points=73, master_counts=9 * 2**13,
                                                                  slave_counts_per_unit=2**20 / (high - low),
                                                                  horner_bits=bits, certify=False)))
    for degree in (1, 3, 5):
        for M, N in ((65534, 32767), (65538, 32769), (2 * 36829, 36829), (3 * 2**28, 3), (3 * 2**29, 3),
                     (2310 * 2**10, 2310)):
            if N > 3000 and degree == 3:
                continue  # (the bound is the same for every degree)
            out.append((f"fold-random-{degree}-{M}-{N}", cb.make_blob(cb.random_table(rng, degree, True, M, N))))
        out.append((f"fold-clamp-{degree}", cb.make_blob(cb.random_table(rng, degree, False, 2310 * 2**10, 2310))))
    return out


def test_horner_bits_32_gives_narrow_tables_and_says_what_it_costs():
    tables = dict(narrow_tables())
    assert all(narrow_horner(t) for t in tables.values())
    drrd = load_cam(ROOT / "firmware_tables" / "cams" / "combination_drrd.toml")
    wide = compile_table(drrd, interp="quintic", points=65, master_counts=36864 * 2)
    narrow = compile_table(drrd, interp="quintic", points=65, master_counts=36864 * 2, horner_bits=32)
    assert not narrow_horner(wide) and narrow_horner(narrow)
    assert narrow.format.work_bits < wide.format.work_bits
    assert narrow.report["quantization_counts"] > wide.report["quantization_counts"]
    assert narrow.report["max_error_counts"] <= narrow.report["predicted_error_counts"]


def fold_extremes(points: int) -> np.ndarray:
    """Masters m = hi 2^32 + lo at the ends of ecam_poly_fold's sum x = (hi % N) c + floor(lo / 2^k)
    + N (N - 1) for a period of N intervals of 2^k: hi % N = N - 1 with lo = 2^32 - 1 (the largest
    x, which the condition in init keeps below 2^32) and hi % N = -(N - 1) with lo = 0 (the
    smallest), for the smallest and the largest such hi of either sign."""
    n = points - 1
    top = (2**31 - 1) - ((2**31 - 1) - (n - 1)) % n  # the largest hi <= INT32_MAX with hi % n = n - 1
    ends = [(n - 1, 2**32 - 1), (top, 2**32 - 1), (-(n - 1), 0), (-top, 0), (n - 1, 0), (-(n - 1), 2**32 - 1)]
    return np.array([((hi % 2**32) << 32 | lo) - ((hi < 0) << 64) for hi, lo in ends], dtype=np.int64)


@functools.lru_cache(maxsize=1)
def _cases() -> tuple:
    """(name, blob, queries, expected position, expected slope): the same (seeded) cases for every
    path, built and looked up in Python once."""
    out = []
    for csv in sorted((FIRMWARE / "vectors").glob("*.csv")):
        rows = np.loadtxt(csv, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
        out.append((csv.stem, csv.with_suffix(".bin").read_bytes(), rows[:, 0]))
    rng = np.random.default_rng(27)
    for name, table in narrow_tables() + mask_tables():
        m = table.master_counts
        queries = np.concatenate([np.array([0, 1, m - 1, m, -1, -m, 2**63 - 1, -(2**63)], dtype=np.int64),
                                  rng.integers(-3 * m, 3 * m, 3000), rng.integers(-(2**63), 2**63 - 1, 1000)])
        out.append((name, table.to_bytes(), queries.astype(np.int64)))
    edges = np.array([0, 1, -1, 2**31, -(2**31), 2**32 - 1, -(2**32), 2**63 - 1, -(2**63)], dtype=np.int64)
    rng_fold = np.random.default_rng(2710)
    for name, table in fold_tables(rng_fold):
        blob = table if isinstance(table, bytes) else table.to_bytes()
        parsed = CamTable.from_bytes(blob)
        m = parsed.master_counts
        queries = np.concatenate([edges, np.array([m - 1, m, -m, -m - 1]), fold_extremes(parsed.points),
                                  rng_fold.integers(-3 * m, 3 * m, 1000),
                                  rng_fold.integers(-(2**63), 2**63 - 1, 3000, endpoint=True)])
        out.append((name, blob, queries.astype(np.int64)))
    for degree in (1, 3, 5):
        for periodic in (True, False):
            for M, N in ((2**20, 64), (360_000, 60), (3, 1)):
                table = cb.random_table(rng, degree, periodic, M, N)
                out.append((f"random-{degree}-{periodic}-{M}", cb.make_blob(table), cb.random_queries(rng, table, 2000)))
        # a negative ramp (S = -5, version 3), through the mask kernels and through the ramp's
        for M, N in ((2**20, 64), (360_000, 60)):
            table = dataclasses.replace(cb.random_table(rng, degree, True, M, N), net_num=-5 * M + 3, ramp=True)
            out.append((f"random-ramp-{degree}-{M}", cb.make_blob(table), cb.random_queries(rng, table, 2000)))
    expected = []
    for name, blob, queries in out:
        position, slope = CamTable.from_bytes(blob).lookup(queries, with_slope=True)
        expected.append((name, blob, queries, cb.int32_wrap(np.asarray(position)), np.asarray(slope)))
    return tuple(expected)


@pytest.mark.parametrize("path", list(PATHS))
def test_the_expanded_form_looks_up_bit_for_bit(drivers, tmp_path, path):
    """ecam_target lookup checks ecam_poly_position against ecam_table_position on every query
    (exit 1 on a difference); the outputs are compared with the Python lookup here."""
    for name, blob, queries, position, slope in _cases():
        (tmp_path / "t.bin").write_bytes(blob)
        queries.astype("<i8").tofile(tmp_path / "q.i64")
        proc = subprocess.run([str(drivers[path]), "lookup", "t.bin", "q.i64", "o.bin"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, f"{path} {name}: {proc.stdout} {proc.stderr}"
        got = np.fromfile(tmp_path / "o.bin", dtype="<i4").astype(np.int64).reshape(-1, 2)
        assert np.array_equal(got[:, 0], position), f"{path} {name}"
        assert np.array_equal(got[:, 1], slope), f"{path} {name}"


HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include "ecam_host_io.h"
#include "ecam_table.h"

int main(int argc, char **argv)
{
    size_t len = 0;
    unsigned char *blob = ecam_host_read_file(argv[1], &len);
    static int64_t buffer[1 << 16];
    ecam_table table;
    ecam_table never = {0};
    ecam_poly poly;
    ecam_poly zero = {0};
    size_t need;
    int rc;

    (void)argc;
    printf("bytes_not_ready=%u\n", (unsigned)ecam_poly_bytes(&never));
    printf("init_null_poly=%d\n", ecam_poly_init(NULL, &never, buffer, sizeof buffer));
    printf("init_null_table=%d\n", ecam_poly_init(&poly, NULL, buffer, sizeof buffer));
    rc = ecam_poly_init(&poly, &never, buffer, sizeof buffer);
    printf("init_not_ready=%d position=%d\n", rc, (int)ecam_poly_position(&poly, 5));
    printf("zero_position=%d null_position=%d\n", (int)ecam_poly_position(&zero, 5),
           (int)ecam_poly_position(NULL, 5));
    if (ecam_table_init(&table, blob, len) != ECAM_OK) {
        return 1;
    }
    need = ecam_poly_bytes(&table);
    printf("bytes=%u\n", (unsigned)need);
    printf("init_null_buffer=%d\n", ecam_poly_init(&poly, &table, NULL, sizeof buffer));
    rc = ecam_poly_init(&poly, &table, buffer, need - 1u);
    printf("init_short=%d position=%d\n", rc, (int)ecam_poly_position(&poly, 5));
    rc = ecam_poly_init(&poly, &table, buffer, need);
    printf("init_ok=%d position=%d table=%d\n", rc, (int)ecam_poly_position(&poly, 5),
           (int)ecam_table_position(&table, 5));
    free(blob);
    return 0;
}
"""


def test_the_expansion_api(tmp_path):
    """The RAM the expansion takes is (points - 1) x (degree + 1) x 8 bytes; a short buffer, a NULL
    and a table that is not ready are refused with their codes, and the refused poly is not ready."""
    source = tmp_path / "harness.c"
    source.write_text(HARNESS)
    exe = _compile(tmp_path / "harness", [source, FIRMWARE / "ecam_host_io.c", FIRMWARE / "ecam_table.c"],
                   ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"])
    blob = FIRMWARE / "vectors" / "combination_drrd_quintic.bin"
    table = CamTable.from_bytes(blob.read_bytes())
    proc = subprocess.run([str(exe), str(blob)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    got = dict(line.split("=", 1) for line in proc.stdout.splitlines())
    invalid = str(-(2**31))
    assert got["bytes_not_ready"] == "0"
    assert got["init_null_poly"] == "-9" and got["init_null_table"] == "-9"
    assert got["init_not_ready"] == f"-32 position={invalid}"  # ECAM_E_UNINITIALISED
    assert got["zero_position"] == f"{invalid} null_position={invalid}"
    assert int(got["bytes"]) == (table.points - 1) * 6 * 8
    assert got["init_null_buffer"] == "-9"
    assert got["init_short"] == f"-35 position={invalid}"  # ECAM_E_BUFFER
    assert got["init_ok"] == f"0 position={table.lookup(5)} table={table.lookup(5)}"
