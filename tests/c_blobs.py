"""Independent pure-Python writer and reference lookup for ecam table blobs (FORMAT.md, versions 1 to 3).

This is a test helper, not a test file. It is written straight from firmware_tables/FORMAT.md and
imports nothing from ``ecam``, so it serves as a second oracle next to ``ecam.CamTable``:

* :func:`make_blob` packs a header with :mod:`struct` and :func:`zlib.crc32` (any header field can
  be overridden, to build blobs that break exactly one rule);
* :func:`reference_lookup` follows the "Lookup" section step by step with plain Python ints.
  Python ints never overflow, so every intermediate is checked against the int64 range and every
  output against int32: a table that would overflow in C raises :class:`OverflowError` here
  instead of silently agreeing or disagreeing;
* :func:`certify` applies FORMAT.md's "Overflow proof" (the rules both loaders apply: a
  sufficient bound on every intermediate of every interval for all tau at once), and
  :func:`random_table` draws random tables that pass it.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

HEADER_BYTES = 64
FORMAT_VERSION = 1
MAGIC = b"ECAM"
INT64_MIN = -(1 << 63)
INT64_MAX = (1 << 63) - 1
INT32_MIN = -(1 << 31)
INT32_MAX = (1 << 31) - 1
SLOPE_FRACTION_BITS = 16
ARRAYS_PER_DEGREE = {1: 1, 3: 2, 5: 3}

# (name, struct code) in blob order; header_crc32 (offset 60) is appended by make_blob.
HEADER_FIELDS = (
    ("magic", "4s"),
    ("format_version", "H"),
    ("header_bytes", "H"),
    ("degree", "B"),
    ("flags", "B"),
    ("step_shift", "b"),
    ("tau_bits", "B"),
    ("work_bits", "B"),
    ("slope_bits", "B"),
    ("curvature_bits", "B"),
    ("slope_preshift", "B"),
    ("points", "I"),
    ("master_counts", "I"),
    ("step_counts", "I"),
    ("position_bits", "B"),
    ("reserved_29", "3s"),
    ("tau_recip", "Q"),
    ("payload_bytes", "I"),
    ("payload_crc32", "I"),
    ("reserved_48", "12s"),
)
HEADER_STRUCT = struct.Struct("<" + "".join(code for _, code in HEADER_FIELDS))
assert HEADER_STRUCT.size == 60

# Byte offset of each header field, for tests that patch raw bytes.
FIELD_OFFSETS = {}
_offset = 0
for _name, _code in HEADER_FIELDS:
    FIELD_OFFSETS[_name] = _offset
    _offset += struct.calcsize("<" + _code)
FIELD_OFFSETS["header_crc32"] = 60
del _offset, _name, _code


def ceil_log2(n: int) -> int:
    """Smallest e with 2**e >= n (n >= 1)."""
    return (n - 1).bit_length()


def is_power_of_two(n: int) -> bool:
    return n > 0 and n & (n - 1) == 0


@dataclass(frozen=True)
class Table:
    """Everything a blob holds, in spec names; derived header fields are properties."""

    degree: int
    periodic: bool
    master_counts: int
    tau_bits: int
    work_bits: int
    slope_bits: int
    curvature_bits: int
    slope_preshift: int
    position_bits: int
    position: tuple
    slope: tuple = ()
    curvature: tuple = ()
    net_num: int = 0  # net stroke N/D counts per period (format version 2 when N != 0)
    net_den: int = 1
    ramp: bool = False  # format version 3: the data relative to the ramp S m (FORMAT.md step 8)

    @property
    def ramp_slope(self) -> int:
        """S = floor(N / (D M)) for version 3, else 0."""
        return self.net_num // (self.net_den * self.master_counts) if self.ramp else 0

    @property
    def points(self) -> int:
        return len(self.position)

    @property
    def intervals(self) -> int:
        return self.points - 1

    @property
    def step_counts(self) -> int:
        h, rest = divmod(self.master_counts, self.intervals)
        assert rest == 0, "N * h must equal M"
        return h

    @property
    def step_shift(self) -> int:
        h = self.step_counts
        return h.bit_length() - 1 if is_power_of_two(h) else -1

    @property
    def tau_recip(self) -> int:
        return -(-(1 << (32 + self.tau_bits)) // self.step_counts)  # ceil(2^(32+F) / h)

    def payload(self) -> bytes:
        arrays = [self.position, self.slope, self.curvature][: ARRAYS_PER_DEGREE[self.degree]]
        for array in arrays:
            assert len(array) == self.points
        return b"".join(struct.pack(f"<{self.points}i", *array) for array in arrays)

    def header_values(self) -> dict:
        """Header fields (without header_crc32) as FORMAT.md defines them for this table."""
        payload = self.payload()
        return {
            "magic": MAGIC,
            "format_version": 3 if self.ramp else 2 if self.net_num else FORMAT_VERSION,
            "header_bytes": HEADER_BYTES,
            "degree": self.degree,
            "flags": 1 if self.periodic else 0,
            "step_shift": self.step_shift,
            "tau_bits": self.tau_bits,
            "work_bits": self.work_bits,
            "slope_bits": self.slope_bits,
            "curvature_bits": self.curvature_bits,
            "slope_preshift": self.slope_preshift,
            "points": self.points,
            "master_counts": self.master_counts,
            "step_counts": self.step_counts,
            "position_bits": self.position_bits,
            "reserved_29": bytes(3),
            "tau_recip": self.tau_recip,
            "payload_bytes": len(payload),
            "payload_crc32": zlib.crc32(payload),
            "reserved_48": struct.pack("<qI", self.net_num, self.net_den) if self.net_num or self.ramp else bytes(12),
        }


def pack_blob(values: dict, payload: bytes, header_crc32: int | None = None) -> bytes:
    """Header from explicit field values (+ CRC of bytes 0..59 unless given) and the payload."""
    head = HEADER_STRUCT.pack(*(values[name] for name, _ in HEADER_FIELDS))
    crc = zlib.crc32(head) if header_crc32 is None else header_crc32
    return head + struct.pack("<I", crc) + payload


def make_blob(table: Table, **overrides) -> bytes:
    """The blob of ``table``; keyword overrides replace header fields before the CRC is taken."""
    values = table.header_values()
    unknown = set(overrides) - set(values)
    assert not unknown, f"unknown header fields {unknown}"
    values.update(overrides)
    return pack_blob(values, table.payload())


def patch(blob: bytes, offset: int, data: bytes, fix_header_crc: bool = True) -> bytes:
    """Overwrite raw bytes (for values struct cannot pack) and, by default, re-seal the header."""
    out = bytearray(blob)
    out[offset : offset + len(data)] = data
    if fix_header_crc:
        out[60:64] = struct.pack("<I", zlib.crc32(bytes(out[:60])))
    return bytes(out)


# --------------------------------------------------------------------------------------------
# Reference lookup, literally FORMAT.md "Lookup of master position m"
# --------------------------------------------------------------------------------------------


def _i64(x: int) -> int:
    """Every intermediate must be a signed 64-bit value (FORMAT.md Notation)."""
    if not INT64_MIN <= x <= INT64_MAX:
        raise OverflowError(f"intermediate {x} leaves int64")
    return x


def _i32(x: int) -> int:
    if not INT32_MIN <= x <= INT32_MAX:
        raise OverflowError(f"output {x} leaves int32")
    return x


def asr(x: int, s: int) -> int:
    """floor(x / 2^s); Python's >> on ints is exactly that."""
    return x >> s


def coefficients(table: Table, i: int) -> list:
    """Step 4: [None, c1, ..., cn] of interval i in Q(W), each checked against int64."""
    W = table.work_bits
    y0, y1 = table.position[i], table.position[i + 1]
    D = _i64(_i64(y1 - y0) * 2 ** (W - table.position_bits))
    if table.degree == 1:
        return [None, D]
    a0 = _i64(table.slope[i] * 2 ** (W - table.slope_bits))
    a1 = _i64(table.slope[i + 1] * 2 ** (W - table.slope_bits))
    if table.degree == 3:
        c2 = _i64(_i64(_i64(3 * D) - _i64(2 * a0)) - a1)
        c3 = _i64(_i64(a0 + a1) - _i64(2 * D))
        return [None, a0, c2, c3]
    b0 = _i64(table.curvature[i] * 2 ** (W - table.curvature_bits))
    b1 = _i64(table.curvature[i + 1] * 2 ** (W - table.curvature_bits))
    c3 = _sum64([10 * D, -6 * a0, -4 * a1, -3 * b0, b1])
    c4 = _sum64([-15 * D, 8 * a0, 7 * a1, 3 * b0, -2 * b1])
    c5 = _sum64([6 * D, -3 * a0, -3 * a1, -b0, b1])
    return [None, a0, b0, c3, c4, c5]


def _sum64(terms: list) -> int:
    """Left-to-right sum with every term and partial sum checked against int64."""
    total = _i64(terms[0])
    for term in terms[1:]:
        total = _i64(total + _i64(term))
    return total


def reference_lookup(table: Table, m: int) -> tuple:
    """(position, slope) of master position m, by the letter of FORMAT.md, in Python ints. With a
    net stroke N/D (version 2) the position adds step 7's floor((k N + floor(D/2)) / D) for the
    k = floor(m / M) whole periods, modulo 2^64 as an int64 (the C runtime returns its low 32
    bits: :func:`int32_wrap`)."""
    position, slope = _lookup_without_net(table, m)
    if table.net_num:
        turns = m // table.master_counts
        position += (turns * table.net_num + table.net_den // 2) // table.net_den
        position += table.ramp_slope * (m % table.master_counts)  # step 8 (version 3)
        position = (position + 2**63) % 2**64 - 2**63
    return position, slope + table.ramp_slope * 2**SLOPE_FRACTION_BITS


def int32_wrap(value):
    """The int32 two's-complement wrap of positions (what the C runtime returns)."""
    if np.ndim(value) == 0:
        return (int(value) + 2**31) % 2**32 - 2**31
    return np.asarray(value, dtype=np.int64).astype(np.int32).astype(np.int64)


def _lookup_without_net(table: Table, m: int) -> tuple:
    M, N, h = table.master_counts, table.intervals, table.step_counts
    F, W, P, R = table.tau_bits, table.work_bits, table.slope_preshift, table.tau_recip
    Qy, n = table.position_bits, table.degree
    # 1. Range.
    halfy = 2 ** (Qy - 1) if Qy > 0 else 0
    if table.periodic:
        m_local = m % M  # Python's % is floor modulo: 0 <= m_local < M
    elif m < 0:
        return _i32(asr(_i64(table.position[0] + halfy), Qy)), 0
    elif m >= M:
        return _i32(asr(_i64(table.position[N] + halfy), Qy)), 0
    else:
        m_local = m
    # 2. Interval.
    i = m_local // h
    t = m_local - i * h
    # 3. Fraction.
    tau = _i64(t * R) // 2**32
    if not 0 <= tau < 2**F:
        raise AssertionError(f"tau {tau} outside [0, 2^{F})")
    # 4. Coefficients.
    c = coefficients(table, i)
    # 5. Position.
    r = c[n]
    for k in range(n - 1, 0, -1):
        r = _i64(c[k] + asr(_i64(r * tau), F))
    half = 2 ** (W - 1) if W > 0 else 0
    y0 = _i64(table.position[i] * 2 ** (W - Qy))
    position = _i32(asr(_i64(_i64(y0 + asr(_i64(r * tau), F)) + half), W))
    # 6. Slope.
    q = _i64(n * c[n])
    for k in range(n - 1, 0, -1):
        q = _i64(_i64(k * c[k]) + asr(_i64(q * tau), F))
    slope = _i32(asr(_i64(asr(q, P) * R), SLOPE_FRACTION_BITS + F + W - P))
    return position, slope


# --------------------------------------------------------------------------------------------
# Certification: FORMAT.md "Overflow proof", the rules both loaders apply, written from the spec
# --------------------------------------------------------------------------------------------

# Dn and the weights C(j, k) * Dn / C(n, k) of the Bernstein coefficients, from FORMAT.md.
BERNSTEIN = {
    1: (1, [[], [1]]),
    3: (3, [[], [1], [2, 1], [3, 3, 3]]),
    5: (10, [[], [2], [4, 1], [6, 3, 1], [8, 6, 4, 2], [10, 10, 10, 10, 10]]),
}
PROOF_RULES = (
    "ECAM_E_POINT_RANGE", "ECAM_E_HORNER_RANGE", "ECAM_E_SUM_RANGE", "ECAM_E_POSITION_RANGE",
    "ECAM_E_SLOPE_HORNER_RANGE", "ECAM_E_SLOPE_PRODUCT", "ECAM_E_SLOPE_RANGE",
)  # fmt: skip


class ProofError(OverflowError):
    """A table the loaders must reject; ``rule`` is the C status name, ``interval`` where."""

    def __init__(self, rule: str, interval: int):
        super().__init__(f"{rule} at interval {interval}")
        self.rule = rule
        self.interval = interval


def exact_coefficients(table: Table, i: int) -> list:
    """[None, c1, ..., cn] of interval i as unbounded ints (FORMAT.md step 4)."""
    W = table.work_bits
    y0 = table.position[i] * 2 ** (W - table.position_bits)
    D = table.position[i + 1] * 2 ** (W - table.position_bits) - y0
    if table.degree == 1:
        return [None, D]
    a0 = table.slope[i] * 2 ** (W - table.slope_bits)
    a1 = table.slope[i + 1] * 2 ** (W - table.slope_bits)
    if table.degree == 3:
        return [None, a0, 3 * D - 2 * a0 - a1, a0 + a1 - 2 * D]
    b0 = table.curvature[i] * 2 ** (W - table.curvature_bits)
    b1 = table.curvature[i + 1] * 2 ** (W - table.curvature_bits)
    return [None, a0, b0, 10 * D - 6 * a0 - 4 * a1 - 3 * b0 + b1,
            -15 * D + 8 * a0 + 7 * a1 + 3 * b0 - 2 * b1, 6 * D - 3 * a0 - 3 * a1 - b0 + b1]


def proof_failure(table: Table):
    """The first rule of FORMAT.md's overflow proof the table breaks, interval by interval and
    rule by rule, as (rule, interval); None when the loaders must accept it."""
    n, F, W, P, R = table.degree, table.tau_bits, table.work_bits, table.slope_preshift, table.tau_recip
    T = 2**F - 1
    two63 = 2**63
    scale, weights = BERNSTEIN[n]
    for i in range(table.intervals):
        y0 = table.position[i] * 2 ** (W - table.position_bits)
        y1 = table.position[i + 1] * 2 ** (W - table.position_bits)
        if abs(y0) >= 2**62 or abs(y1) >= 2**62:
            return "ECAM_E_POINT_RANGE", i
        c = exact_coefficients(table, i)
        r = abs(c[n])
        horner_ok = r * T < two63
        for k in range(n - 1, 0, -1):
            r = abs(c[k]) + r + 1
            horner_ok = horner_ok and r * T < two63
        if not horner_ok:
            return "ECAM_E_HORNER_RANGE", i
        if abs(y0) + r + 2**W >= two63:
            return "ECAM_E_SUM_RANGE", i
        for row in weights:
            b = scale * y0 + sum(w * c[k] for k, w in enumerate(row, start=1))
            if abs(b) + scale * n > scale * (2**31 - 1) * 2**W:
                return "ECAM_E_POSITION_RANGE", i
        q = n * abs(c[n])
        slope_ok = True
        for k in range(n - 1, 0, -1):
            slope_ok = slope_ok and q * T < two63
            q = k * abs(c[k]) + q + 1
        if not (slope_ok and q < two63):
            return "ECAM_E_SLOPE_HORNER_RANGE", i
        s = -(-q // 2**P)  # ceil(q / 2^P)
        if s * R >= two63:
            return "ECAM_E_SLOPE_PRODUCT", i
        if s * R > (2**31 - 1 - abs(table.ramp_slope) * 2**SLOPE_FRACTION_BITS) * 2 ** (SLOPE_FRACTION_BITS + F + W - P):
            return "ECAM_E_SLOPE_RANGE", i
    return None


def certify(table: Table) -> None:
    """Raise :class:`ProofError` (an OverflowError) unless the table passes FORMAT.md's overflow
    proof, i.e. unless both loaders accept it. The proof is sufficient: every lookup of a
    certified table keeps its intermediates in int64, which :func:`reference_lookup` checks on
    every query it evaluates."""
    F, W, P, R = table.tau_bits, table.work_bits, table.slope_preshift, table.tau_recip
    if not (0 <= SLOPE_FRACTION_BITS + F + W - P <= 63 and table.position_bits <= W):
        raise OverflowError("shift counts out of range")
    if (table.step_counts - 1) * R > INT64_MAX:
        raise OverflowError("t * R")
    failure = proof_failure(table)
    if failure is not None:
        raise ProofError(*failure)


# --------------------------------------------------------------------------------------------
# Random valid tables and queries
# --------------------------------------------------------------------------------------------


def random_table(
    rng: np.random.Generator,
    degree: int,
    periodic: bool,
    master_counts: int,
    intervals: int,
    tau_bits: int | None = None,
    work_bits: int | None = None,
    position_bits: int | None = None,
    delta_bits: int | None = None,
) -> Table:
    """A random table with valid header fields whose lookups provably stay in range.

    tau_bits (non-power-of-two steps only), work_bits, position_bits and delta_bits (log2 of the
    largest position change per interval, in whole counts) are drawn at random unless given.
    """
    M, N = master_counts, intervals
    h = M // N
    assert N * h == M and 2 <= M <= 2**31 and 1 <= h <= 2**30
    if is_power_of_two(h):
        F = h.bit_length() - 1
    else:
        F = int(rng.integers(ceil_log2(h), 31)) if tau_bits is None else tau_bits
    # Changes of up to h * 2^12 counts per step keep the Q16 slope output near 2^28, and W is
    # capped so the Horner products stay near 2^62; certify() has the final word, and attempts
    # that fail it are redrawn with ever smaller changes.
    log_h = h.bit_length() - 1
    for attempt in range(400):
        shrink = attempt // 20
        if delta_bits is None:
            db = max(0, int(rng.integers(0, min(24, log_h + 12) + 1)) - shrink)
        else:
            db = delta_bits
        if position_bits is not None:
            Qy = position_bits
        else:
            Qy = int(rng.integers(0, min(30, 40 if work_bits is None else work_bits) + 1))
        stored_db = min(db + Qy, 28)  # stored positions stay within +-2^30
        if degree == 1:
            W = Qy
        elif work_bits is not None:
            W = work_bits
        else:
            W = Qy + int(rng.integers(0, max(0, min(40 - Qy, 31, 54 - F - stored_db)) + 1))
        Qa = 0 if degree == 1 else int(rng.integers(0, W + 1))
        Qb = int(rng.integers(0, W + 1)) if degree == 5 else 0
        real_db = stored_db - Qy
        position = _random_walk(rng, N + 1, stored_db)
        slope = _random_ints(rng, N + 1, real_db + Qa + 1) if degree >= 3 else ()
        curvature = _random_ints(rng, N + 1, real_db + Qb) if degree == 5 else ()
        for P in _preshift_candidates(rng, F, W):
            table = Table(
                degree=degree, periodic=periodic, master_counts=M, tau_bits=F, work_bits=W,
                slope_bits=Qa, curvature_bits=Qb, slope_preshift=P, position_bits=Qy,
                position=position, slope=slope, curvature=curvature,
            )  # fmt: skip
            try:
                certify(table)
            except OverflowError:
                continue
            return table
    raise AssertionError("no certifiable random table found")


def _preshift_candidates(rng: np.random.Generator, F: int, W: int) -> list:
    """Valid P values (16 + F + W - P in 0..63), a random one first, then ascending."""
    lo = max(0, SLOPE_FRACTION_BITS + F + W - 63)
    hi = SLOPE_FRACTION_BITS + F + W
    first = int(rng.integers(lo, hi + 1))
    return [first] + [p for p in range(lo, hi + 1) if p != first]


def _random_ints(rng: np.random.Generator, count: int, bits: int) -> tuple:
    bits = max(0, min(bits, 31))
    return tuple(int(v) for v in rng.integers(-(2**bits) + 1, 2**bits, size=count))


def _random_walk(rng: np.random.Generator, count: int, delta_bits: int) -> tuple:
    """Stored positions within +-2^30 whose neighbours differ by less than 2^delta_bits."""
    y = int(rng.integers(-(2**28), 2**28))
    out = [y]
    for _ in range(count - 1):
        step = int(rng.integers(-(2**delta_bits) + 1, 2**delta_bits))
        y = y - step if abs(y + step) > 2**29 else y + step
        out.append(y)
    return tuple(out)


def edge_queries(table: Table) -> list:
    """Master positions where wrap, clamp, interval and 64-bit edges meet."""
    M, h = table.master_counts, table.step_counts
    centres = [0, M, -M, 2 * M, -2 * M, h, M - h, 7 * M, -7 * M]
    centres += [s * 2**e for s in (1, -1) for e in (31, 32, 33, 62)]
    centres += [INT64_MIN, INT64_MAX, (INT64_MAX // M) * M, (INT64_MIN // M) * M]
    centres += [(INT64_MAX // M - 1) * M, (INT64_MIN // M + 1) * M]
    out = []
    for c in centres:
        for d in range(-3, 4):
            out.append(c + d)
    out += [k * h + d for k in range(table.intervals + 1) for d in (-1, 0, 1)][:3000]
    return sorted({min(max(v, INT64_MIN), INT64_MAX) for v in out})


def random_queries(rng: np.random.Generator, table: Table, count: int) -> np.ndarray:
    """``count`` int64 master positions: all edges first, then a mix of wide and near-edge values.

    For non-periodic tables two of the six parts are drawn inside [0, M], where the interpolation
    happens, instead of across all periods.
    """
    M, h, N = table.master_counts, table.step_counts, table.intervals
    edges = np.array(edge_queries(table), dtype=np.int64)
    rest = count - len(edges)
    k = rest // 6
    wide = rng.integers(INT64_MIN, INT64_MAX, size=k, dtype=np.int64, endpoint=True)
    local = rng.integers(-3 * M, 4 * M, size=k, dtype=np.int64)
    # Near a period or interval boundary, at any of the representable periods.
    if table.periodic:
        periods = rng.integers(-(2**63 // M), INT64_MAX // M, size=k, dtype=np.int64)
    else:
        periods = np.zeros(k, dtype=np.int64)
    boundary = periods * M + rng.integers(0, N + 1, size=k, dtype=np.int64) * h
    boundary = _clip_add(boundary, rng.integers(-2, 3, size=k, dtype=np.int64))
    # Near +-2^31, +-2^32 and the ends of int64.
    centres = np.array([2**31, -(2**31), 2**32, -(2**32), INT64_MIN, INT64_MAX], dtype=np.int64)
    spread = rng.integers(-4 * M, 4 * M + 1, size=k, dtype=np.int64)
    near = _clip_add(rng.choice(centres, size=k), spread)
    mid = rng.integers(-(2**40), 2**40, size=k, dtype=np.int64)
    inside = rng.integers(0, M, size=rest - 5 * k, dtype=np.int64)
    if table.periodic:
        inside = rng.integers(INT64_MIN // 2, INT64_MAX // 2, size=inside.size, dtype=np.int64)
    return np.concatenate([edges, wide, local, boundary, near, mid, inside])


def _clip_add(a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """a + d saturated to int64 (exact: done in Python ints)."""
    return np.array(
        [min(max(int(x) + int(y), INT64_MIN), INT64_MAX) for x, y in zip(a.tolist(), d.tolist())],
        dtype=np.int64,
    )
