"""The C loader (ecam_table_init) and the Python loader (CamTable.from_bytes) accept exactly the
same blobs, reject the others with the same rule, and agree bit for bit on every blob they accept
(the C position being the int32 wrap of Python's, which a net stroke can take past int32).

A seeded differential fuzz: golden, shipped and random tables are mutated header field by header
field (values at and around each rule's edges, random values, consistent rewrites of the fields
that depend on each other), and payload word by payload word, with the CRCs recomputed so that
the field rules and the overflow proof are reached rather than stopped at the CRC. Every blob
goes through both loaders; the C status and the Python status (TableFormatError.status) must be
equal. On a sample of accepted blobs both lookups run on edge and random masters.
Deterministic (fixed seeds), a few seconds.
"""

from __future__ import annotations

import os
import re
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from ecam import CamTable, TableFormatError
from ecam.table import LOADER_STATUS

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import c_blobs as cb  # noqa: E402

pytestmark = pytest.mark.slow  # compiles C

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware_tables"
SEED = 20261122
MUTANTS = 6000
LOOKUP_SAMPLE = 120
NAMES = {code: name for name, code in LOADER_STATUS.items()}
NAMES[0] = "ECAM_OK"


@pytest.fixture(scope="module")
def cli(tmp_path_factory) -> Path:
    cc = next((shutil.which(c) for c in (os.environ.get("CC", "cc"), "cc", "gcc", "clang") if c and shutil.which(c)), None)
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    out = tmp_path_factory.mktemp("parity") / "ecam_cli"
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-I", str(FIRMWARE), "-o", str(out),
           str(FIRMWARE / "ecam_cli.c"), str(FIRMWARE / "ecam_host_io.c"), str(FIRMWARE / "ecam_table.c")]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out


def c_statuses(cli: Path, directory: Path, blobs: list) -> list:
    """The C loader's status name of every blob (one `ecam_cli --check` process)."""
    directory.mkdir(exist_ok=True)
    paths = []
    for k, blob in enumerate(blobs):
        path = directory / f"{k:05d}.ecam"
        path.write_bytes(blob)
        paths.append(str(path))
    proc = subprocess.run([str(cli), "--check", *paths], capture_output=True, text=True)
    lines = proc.stdout.splitlines()
    assert len(lines) == len(blobs), proc.stderr
    return ["ECAM_OK" if line == "ok" else line.split()[2] for line in lines]


def python_status(blob: bytes) -> str:
    try:
        CamTable.from_bytes(blob)
    except TableFormatError as exc:
        assert "\n" not in str(exc) and exc.status in str(exc)
        return exc.status
    return "ECAM_OK"



# --------------------------------------------------------------------------------------------
# Blobs
# --------------------------------------------------------------------------------------------

OFFSETS = cb.FIELD_OFFSETS
CODES = dict(cb.HEADER_FIELDS)


def base_blobs() -> list:
    """Valid blobs of every degree, step kind and periodicity, plus the shipped ones."""
    out = [p.read_bytes() for p in sorted((FIRMWARE / "vectors").glob("*.bin"))]
    out += [p.read_bytes() for p in sorted((FIRMWARE / "tables").glob("*.bin"))]
    rng = np.random.default_rng(SEED)
    for degree in (1, 3, 5):
        for periodic in (True, False):
            for M, N in ((2**16, 16), (360_000, 60), (3000, 2), (2**31, 2), (2, 2)):
                out.append(cb.make_blob(cb.random_table(rng, degree, periodic, M, N)))
    # version 3 (the data relative to the ramp S m): a version-2 table read as one (S = 10), and
    # with a net stroke of 0/1 (ECAM_E_RAMP); the drum's golden table is among the vectors
    ramp = bytearray((FIRMWARE / "vectors" / "rotary_knife_cubic.bin").read_bytes())
    put(ramp, "format_version", 3)
    out.append(reseal(ramp))
    struct.pack_into("<qI", ramp, OFFSETS["reserved_48"], 0, 1)
    out.append(reseal(ramp))
    return out


def reseal(blob: bytearray, payload_crc: bool = False) -> bytes:
    """Recompute the CRCs, so the mutation reaches the field rules and the overflow proof."""
    if payload_crc:
        blob[OFFSETS["payload_crc32"]:OFFSETS["payload_crc32"] + 4] = struct.pack("<I", zlib.crc32(bytes(blob[64:])))
    blob[60:64] = struct.pack("<I", zlib.crc32(bytes(blob[:60])))
    return bytes(blob)


def put(blob: bytearray, name: str, value: int) -> None:
    code = "<" + CODES[name]
    size = struct.calcsize(code)
    if code[-1] in "bB":
        value &= 0xFF
        value = value - 256 if code[-1] == "b" and value > 127 else value
    else:
        value &= (1 << (8 * size)) - 1
    struct.pack_into(code, blob, OFFSETS[name], value)


def get(blob, name: str) -> int:
    return struct.unpack_from("<" + CODES[name], blob, OFFSETS[name])[0]


INTERESTING = {
    "B": (0, 1, 2, 3, 5, 10, 15, 16, 17, 22, 23, 29, 30, 31, 32, 33, 39, 40, 41, 46, 47, 62, 63, 64, 65, 85, 86, 87, 127, 128, 255),
    "b": (-128, -2, -1, 0, 1, 2, 9, 10, 11, 12, 13, 14, 29, 30, 31, 127),
    "H": (0, 1, 63, 64, 65, 0xFFFF),
    "I": (0, 1, 2, 3, 4, 2**30 - 1, 2**30, 2**30 + 1, 2**31 - 1, 2**31, 2**31 + 1, 2**32 - 1),
    "Q": (0, 1, 2**32 - 1, 2**32, 2**32 + 1, 2**62, 2**63, 2**64 - 1),
}
MUTABLE = [name for name, code in cb.HEADER_FIELDS if code in INTERESTING] + ["reserved_29", "reserved_48"]


def consistent(blob: bytearray) -> None:
    """Rewrite step_shift, tau_recip and payload_bytes to follow the other fields, so that the
    later rules (format bits, the proof) are reached."""
    h = get(blob, "step_counts")
    F = get(blob, "tau_bits")
    if h >= 1:
        put(blob, "step_shift", h.bit_length() - 1 if h & (h - 1) == 0 else -1)
        if F <= 40:
            put(blob, "tau_recip", -(-(1 << (32 + F)) // h))


def mutate(rng: np.random.Generator, base: bytes) -> bytes:
    blob = bytearray(base)
    kind = int(rng.integers(0, 10))
    if kind <= 4:  # one to three fields at edge or random values
        for _ in range(int(rng.integers(1, 4))):
            name = MUTABLE[int(rng.integers(0, len(MUTABLE)))]
            if name.startswith("reserved"):
                offset = OFFSETS[name] + int(rng.integers(0, 3 if name == "reserved_29" else 12))
                blob[offset] = int(rng.integers(1, 256))
                continue
            code = CODES[name]
            current = get(blob, name)
            choice = int(rng.integers(0, 4))
            if choice == 0:
                value = int(rng.choice(INTERESTING[code]))
            elif choice == 1:
                value = current + int(rng.integers(-3, 4))
            elif choice == 2:
                value = int(rng.integers(0, 2**63)) >> int(rng.integers(0, 63))
            else:
                value = current ^ (1 << int(rng.integers(0, 8 * struct.calcsize(code))))
            put(blob, name, value)
        if rng.random() < 0.5:
            consistent(blob)
        return reseal(blob)
    if kind <= 7:  # the fixed-point format: shifts redrawn inside (or just past) their rules
        degree = get(blob, "degree")
        qy = int(rng.integers(0, 32))
        w = qy if degree == 1 else int(rng.integers(max(0, qy - 1), 42))
        put(blob, "position_bits", qy)
        put(blob, "work_bits", w)
        put(blob, "slope_bits", 0 if degree == 1 else int(rng.integers(0, w + 2)))
        put(blob, "curvature_bits", int(rng.integers(0, w + 2)) if degree == 5 else 0)
        if rng.random() < 0.5 and get(blob, "step_shift") < 0:
            put(blob, "tau_bits", int(rng.integers(get(blob, "tau_bits") - 1, 32)))
            consistent(blob)
        scaled = 16 + get(blob, "tau_bits") + w
        put(blob, "slope_preshift", int(rng.integers(max(0, scaled - 64), scaled + 2)))
        return reseal(blob)
    # the payload: words pushed towards the int32 edges, CRCs recomputed (reaches the proof)
    words = (len(blob) - 64) // 4
    if words:
        for _ in range(int(rng.integers(1, 4))):
            k = int(rng.integers(0, words))
            old = struct.unpack_from("<i", blob, 64 + 4 * k)[0]
            value = int(rng.choice([2**31 - 1, -(2**31), 2**30, -(2**30), old * 2, old * 16, old * 1024, -old]))
            struct.pack_into("<i", blob, 64 + 4 * k, max(-(2**31), min(2**31 - 1, value)))
    return reseal(blob, payload_crc=True)


def mutants() -> list:
    rng = np.random.default_rng(SEED + 1)
    bases = base_blobs()
    out = list(bases)
    while len(out) < MUTANTS:
        out.append(mutate(rng, bases[int(rng.integers(0, len(bases)))]))
    return out


# --------------------------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------------------------


def test_issue_14_preshift_blob_is_rejected_by_both(cli, tmp_path):
    """slope_preshift = 16 + F + W = 64 on the shipped combination_drrd table: Python used to accept
    it (and compute a slope of -2^32 where C returns 0). Both loaders now reject it, by the same rule."""
    blob = bytearray((FIRMWARE / "tables" / "combination_drrd.bin").read_bytes())
    assert 16 + blob[11] + blob[12] == 64
    blob[15] = 64
    blob = reseal(blob)
    assert c_statuses(cli, tmp_path / "p64", [blob]) == ["ECAM_E_SLOPE_RANGE"]
    assert python_status(blob) == "ECAM_E_SLOPE_RANGE"


def _c_lookup(cli: Path, path: Path, blob: bytes, queries: np.ndarray) -> np.ndarray:
    path.write_bytes(blob)
    stdin = ("\n".join(map(str, queries.tolist())) + "\n").encode()
    proc = subprocess.run([str(cli), str(path)], input=stdin, capture_output=True)
    assert proc.returncode == 0, proc.stderr
    return np.array(proc.stdout.split(), dtype=np.int64).reshape(-1, 2)


def _probe_masters(rng: np.random.Generator, M: int) -> np.ndarray:
    return np.concatenate([
        np.array([0, 1, M - 1, M, M + 1, -1, -M, 2**62, -(2**62), 2**63 - 1, -(2**63)], dtype=np.int64),
        rng.integers(0, M, 300, dtype=np.int64),
        rng.integers(-(2**63), 2**63 - 1, 60, dtype=np.int64, endpoint=True),
    ])  # fmt: skip


def test_every_slope_preshift_of_the_shipped_tables(cli, tmp_path):
    """Issue 14 item 1 for every P: byte 15 (slope_preshift) set to each of 0..255 on every
    shipped and golden table, header CRC recomputed. Both loaders give the same status for each;
    where they accept (the proof holds for that P, 16 + F + W - P anywhere in 0..63, P past 63
    too), C and Python look up the same positions and slopes, at the ends of the accepted range."""
    paths = sorted((FIRMWARE / "tables").glob("*.bin")) + sorted((FIRMWARE / "vectors").glob("*.bin"))
    blobs = []
    for path in paths:
        base = bytearray(path.read_bytes())
        for P in range(256):
            blob = bytearray(base)
            blob[15] = P
            blobs.append(reseal(blob))
    c = c_statuses(cli, tmp_path / "preshift", blobs)
    py = [python_status(b) for b in blobs]
    differ = [(paths[k // 256].stem, k % 256, c[k], py[k]) for k in range(len(blobs)) if c[k] != py[k]]
    assert not differ, differ[:10]
    assert {"ECAM_OK", "ECAM_E_SLOPE_PRESHIFT", "ECAM_E_SLOPE_RANGE"} <= set(c)
    rng = np.random.default_rng(SEED + 3)
    for n, path in enumerate(paths):
        statuses = c[256 * n:256 * (n + 1)]
        accepted = [P for P, status in enumerate(statuses) if status == "ECAM_OK"]
        scaled = 16 + blobs[256 * n][11] + blobs[256 * n][12]  # 16 + F + W
        assert accepted and max(accepted) < scaled, (path.stem, accepted)  # a zero final shift never proves
        assert statuses[scaled + 1:] == ["ECAM_E_SLOPE_PRESHIFT"] * (255 - scaled)
        for P in sorted({accepted[0], *accepted[-3:]}):
            blob = blobs[256 * n + P]
            table = CamTable.from_bytes(blob)
            queries = _probe_masters(rng, table.master_counts)
            got = _c_lookup(cli, tmp_path / "p.ecam", blob, queries)
            positions, slopes = table.lookup(queries, with_slope=True)
            expected = np.stack([cb.int32_wrap(positions), slopes], 1)
            bad = np.flatnonzero((got != expected).any(axis=1))
            assert not bad.size, f"{path.stem} P={P}: m={queries[bad[0]]} C={tuple(got[bad[0]])} Python={tuple(expected[bad[0]])}"


def test_loaders_accept_exactly_the_same_blobs(cli, tmp_path):
    blobs = mutants()
    c = c_statuses(cli, tmp_path / "mutants", blobs)
    py = [python_status(b) for b in blobs]
    assert all(status in LOADER_STATUS or status == "ECAM_OK" for status in py), set(py) - set(LOADER_STATUS)
    differ = [(k, c[k], py[k]) for k in range(len(blobs)) if c[k] != py[k]]
    assert not differ, f"{len(differ)} of {len(blobs)} blobs judged differently (index, C, Python): {differ[:10]}"
    # The fuzz must reach every rule past the CRC, and accept a good share of its mutants.
    reached = set(c)
    c_rules = set(re.findall(r"(ECAM_E_\w+) = -\d+", (FIRMWARE / "ecam_table.h").read_text()))
    must = c_rules - {"ECAM_E_SHORT", "ECAM_E_MAGIC", "ECAM_E_VERSION", "ECAM_E_HEADER_SIZE", "ECAM_E_HEADER_CRC",
                      "ECAM_E_LENGTH", "ECAM_E_PAYLOAD_CRC", "ECAM_E_FIELD", "ECAM_E_NULL", "ECAM_E_UNINITIALISED",
                      "ECAM_E_BUSY", "ECAM_E_BUFFER"}  # the envelope (a mutant rarely keeps it) and codes that
    # are not loader rules (ECAM_E_BUFFER: ecam_poly_init's buffer)
    assert len(must) == 24, sorted(must)
    assert must <= reached, f"rules never reached: {sorted(must - reached)}"
    accepted = c.count("ECAM_OK")
    assert accepted >= len(blobs) // 10, f"only {accepted} of {len(blobs)} mutants accepted"


def test_accepted_mutants_look_up_alike(cli, tmp_path):
    """On blobs both loaders accept, C and Python agree bit for bit (positions and slopes), so
    the proof really covers every shift the header allows."""
    blobs = mutants()
    statuses = c_statuses(cli, tmp_path / "accepted", blobs)
    accepted = [b for b, s in zip(blobs, statuses) if s == "ECAM_OK"]
    rng = np.random.default_rng(SEED + 2)
    picks = rng.choice(len(accepted), size=min(LOOKUP_SAMPLE, len(accepted)), replace=False)
    for n, k in enumerate(sorted(picks.tolist())):
        blob = accepted[k]
        table = CamTable.from_bytes(blob)
        queries = _probe_masters(rng, table.master_counts)
        got = _c_lookup(cli, tmp_path / f"acc{n}.ecam", blob, queries)
        positions, slopes = table.lookup(queries, with_slope=True)
        expected = np.stack([cb.int32_wrap(positions), slopes], 1)  # C: the int32 wrap (net stroke)
        bad = np.flatnonzero((got != expected).any(axis=1))
        assert not bad.size, f"mutant {k}: m={queries[bad[0]]} C={tuple(got[bad[0]])} Python={tuple(expected[bad[0]])}"
        for m in queries[:11].tolist():  # the scalar path (Python ints) too
            position, slope = table.lookup(m, with_slope=True)
            assert (cb.int32_wrap(position), slope) == tuple(int(v) for v in got[queries.tolist().index(m)])
