"""CamTable: an immutable fixed-point cam table and its integer lookup.

The lookup is the exact mirror of the C reference runtime (``firmware_tables/ecam_table.c``);
both follow ``firmware_tables/FORMAT.md`` step by step: integers only, int64 intermediates,
every intermediate shift floors, the final shift rounds half up.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass

import numpy as np

from .certificate import Certificate
from .errors import InputError, TableFormatError

__all__ = ["TableFormat", "CamTable", "INTERPOLATIONS", "KINDS", "SLOPE_BITS", "HEADER_BYTES", "FORMAT_VERSION", "MAGIC"]

KINDS = {"linear": 1, "cubic": 3, "quintic": 5}
# Every name a user may ask for: a kind, or "auto" (the smallest table of any kind within a tolerance).
INTERPOLATIONS = (*KINDS, "auto")
_KIND_NAMES = {v: k for k, v in KINDS.items()}
SLOPE_BITS = 16
HEADER_BYTES = 64
FORMAT_VERSION = 1
MAGIC = b"ECAM"
MAX_MASTER_COUNTS = 2**31
MAX_STEP_COUNTS = 2**30
MAX_WORK_BITS = 40
_INT32_MAX = 2**31 - 1
_INT64_LIMIT = 2.0**63 * (1 - 1e-9)  # float bounds carry a relative margin
_HEADER = struct.Struct("<4sHHBBbBBBBBIIIB3sQII12sI")
assert _HEADER.size == HEADER_BYTES


@dataclass(frozen=True)
class TableFormat:
    """Every field of a table's fixed-point format (see FORMAT.md for the rules)."""

    degree: int
    periodic: bool
    points: int
    master_counts: int
    step_counts: int
    step_shift: int
    tau_bits: int
    work_bits: int
    slope_bits: int
    curvature_bits: int
    slope_preshift: int
    tau_recip: int
    position_bits: int = 0

    @property
    def interp(self) -> str:
        return _KIND_NAMES[self.degree]

    @property
    def values_per_point(self) -> int:
        return (self.degree + 1) // 2

    @property
    def payload_bytes(self) -> int:
        return self.points * 4 * self.values_per_point

    def validate(self) -> None:
        """Raise TableFormatError naming the first field that breaks its rule."""
        def bad(name, value, rule):
            raise TableFormatError(f"{name} {value!r} should be {rule}")

        if self.degree not in _KIND_NAMES:
            bad("degree", self.degree, "1, 3 or 5")
        if not 2 <= self.points <= 2**32 - 1:
            bad("points", self.points, "in 2..2^32-1")
        if not 2 <= self.master_counts <= MAX_MASTER_COUNTS:
            bad("master_counts", self.master_counts, f"in 2..{MAX_MASTER_COUNTS}")
        if not 1 <= self.step_counts <= MAX_STEP_COUNTS:
            bad("step_counts", self.step_counts, f"in 1..{MAX_STEP_COUNTS}")
        if (self.points - 1) * self.step_counts != self.master_counts:
            bad("step_counts", self.step_counts, f"master_counts / (points - 1) = {self.master_counts}/{self.points - 1}")
        h = self.step_counts
        pow2 = h & (h - 1) == 0
        shift = h.bit_length() - 1 if pow2 else -1
        if self.step_shift != shift:
            bad("step_shift", self.step_shift, f"{shift} for step_counts {h}")
        need = (h - 1).bit_length()  # ceil(log2 h)
        if pow2 and self.tau_bits != need:
            bad("tau_bits", self.tau_bits, f"{need} for step_counts {h}")
        if not need <= self.tau_bits <= 30:
            bad("tau_bits", self.tau_bits, f"in {need}..30")
        if self.tau_recip != -(-(1 << (32 + self.tau_bits)) // h):
            bad("tau_recip", self.tau_recip, "ceil(2^(32+tau_bits)/step_counts)")
        if not 0 <= self.position_bits <= 30:
            bad("position_bits", self.position_bits, "in 0..30")
        if not self.position_bits <= self.work_bits <= MAX_WORK_BITS:
            bad("work_bits", self.work_bits, f"in position_bits={self.position_bits}..{MAX_WORK_BITS}")
        if self.degree == 1 and (self.work_bits != self.position_bits or self.slope_bits or self.curvature_bits):
            bad("work_bits", self.work_bits, "position_bits (with slope_bits and curvature_bits 0) for linear")
        if not 0 <= self.slope_bits <= self.work_bits:
            bad("slope_bits", self.slope_bits, f"in 0..work_bits={self.work_bits}")
        if self.degree != 5 and self.curvature_bits:
            bad("curvature_bits", self.curvature_bits, "0 unless quintic")
        if not 0 <= self.curvature_bits <= self.work_bits:
            bad("curvature_bits", self.curvature_bits, f"in 0..work_bits={self.work_bits}")
        final = SLOPE_BITS + self.tau_bits + self.work_bits - self.slope_preshift
        if self.slope_preshift < 0 or not 0 <= final <= 63:
            bad("slope_preshift", self.slope_preshift, "such that 0 <= 16 + tau_bits + work_bits - slope_preshift <= 63")


@dataclass(frozen=True, eq=False)
class CamTable:
    """A compiled cam table: read-only int32 arrays plus their format and certificate.

    Use :func:`ecam.compile_table` to build one, or :meth:`from_bytes` to load a blob.

    Attributes
    ----------
    format : TableFormat
    positions : numpy.ndarray of int32, shape (points,)
        Slave counts at master counts ``i * step_counts``, in Q``position_bits``.
    slopes : numpy.ndarray of int32 or None
        ``h * dy/dm`` in Q``slope_bits`` (cubic and quintic).
    curvatures : numpy.ndarray of int32 or None
        ``h**2 * d2y/dm2 / 2`` in Q``curvature_bits`` (quintic).
    certificate : Certificate or None
        What the compiler proved and measured (None for a table loaded from bytes).
    report : dict
        The certificate as the documented dictionary (empty for a table loaded from bytes).
    """

    format: TableFormat
    positions: np.ndarray
    slopes: np.ndarray | None = None
    curvatures: np.ndarray | None = None
    certificate: Certificate | None = None

    def __post_init__(self):
        self.format.validate()
        arrays = {"positions": self.positions, "slopes": self.slopes, "curvatures": self.curvatures}
        need = {"positions": True, "slopes": self.format.degree >= 3, "curvatures": self.format.degree == 5}
        for name, array in arrays.items():
            if need[name] != (array is not None):
                raise TableFormatError(f"{name} should be {'given' if need[name] else 'absent'} for {self.format.interp}")
            if array is not None:
                array = np.array(array, dtype=np.int32, copy=True)
                if array.shape != (self.format.points,):
                    raise TableFormatError(f"{name} shape {array.shape} should be ({self.format.points},)")
                array.setflags(write=False)
                object.__setattr__(self, name, array)
        object.__setattr__(self, "_coefficients", None)

    # convenience -----------------------------------------------------------------------------
    @property
    def report(self) -> dict:
        return {} if self.certificate is None else self.certificate.report(self)

    @property
    def interp(self) -> str:
        return self.format.interp

    @property
    def points(self) -> int:
        return self.format.points

    @property
    def master_counts(self) -> int:
        return self.format.master_counts

    @property
    def periodic(self) -> bool:
        return self.format.periodic

    @property
    def crc32(self) -> int:
        return zlib.crc32(self._payload())

    @property
    def nbytes(self) -> int:
        return HEADER_BYTES + self.format.payload_bytes

    # lookup ------------------------------------------------------------------------------------
    def coefficient_rows(self) -> tuple[np.ndarray, ...]:
        """Per-interval integers (Y0 * 2^(W-Qy), c1, ..., cn) of FORMAT.md step 4, one contiguous
        array each, computed once: the same integers the C runtime derives on the fly from the
        point data (contiguous columns make the vectorized gathers several times faster)."""
        if self._coefficients is not None:
            return self._coefficients
        f = self.format
        y = self.positions.astype(np.int64) << (f.work_bits - f.position_bits)
        s = None if self.slopes is None else self.slopes.astype(np.int64) << (f.work_bits - f.slope_bits)
        c = None if self.curvatures is None else self.curvatures.astype(np.int64) << (f.work_bits - f.curvature_bits)
        cols = [y[:-1], *hermite_coefficients(f.degree, y, s, c)]
        cols = tuple(np.ascontiguousarray(c) for c in cols)
        for c in cols:
            c.setflags(write=False)
        object.__setattr__(self, "_coefficients", cols)
        return cols

    def _locate(self, master_counts):
        m = _as_counts(master_counts)
        f = self.format
        if f.periodic:
            local = np.mod(m, f.master_counts)  # exact floor modulo (C: reciprocal + correction)
            outside = None
        else:
            outside = (m < 0, m >= f.master_counts)
            local = np.clip(m, 0, f.master_counts - 1)
        local = np.atleast_1d(local)
        if f.step_shift >= 0:
            index = local >> f.step_shift
            tau = np.bitwise_and(local, f.step_counts - 1, out=local)
        else:
            index = local // f.step_counts  # exact quotient (C: reciprocal + correction)
            local -= index * f.step_counts
            np.multiply(local, f.tau_recip, out=local)
            tau = np.right_shift(local, 32, out=local)
        return index, tau, outside

    def lookup(self, master_counts, *, with_slope: bool = False):
        """Slave position in counts at ``master_counts`` (any int64; periodic cams wrap).

        Parameters
        ----------
        master_counts : int or array_like of int
            Master positions in counts. Periodic tables wrap (negative values and values past
            2^32 included); non-periodic tables hold the end positions outside [0, M].
        with_slope : bool
            Also return the slope (Q16 slave counts per master count).

        Returns
        -------
        numpy.ndarray of int64 (or int for a scalar), and the slope array if ``with_slope``.
        """
        if isinstance(master_counts, (int, np.integer)) and not isinstance(master_counts, (bool, np.bool_)):
            return self._lookup_one(int(master_counts), with_slope)
        index, tau, outside = self._locate(master_counts)
        f = self.format
        cols = self.coefficient_rows()
        n, shift, w = f.degree, f.tau_bits, f.work_bits
        # Horner, in place: r = c_k + asr(r * tau, F); every shift floors (numpy >> on int64)
        r = np.take(cols[n], index)
        for k in range(n - 1, -1, -1):
            np.multiply(r, tau, out=r)
            np.right_shift(r, shift, out=r)
            r += np.take(cols[k], index)
        if w:
            r += 1 << (w - 1)
            np.right_shift(r, w, out=r)
        position = r
        if outside is not None:
            below, above = np.atleast_1d(outside[0]), np.atleast_1d(outside[1])
            position[below] = self._end_position(0)
            position[above] = self._end_position(-1)
        position = _unwrap(position, master_counts)
        if not with_slope:
            return position
        q = np.take(cols[n], index) * n
        for k in range(n - 1, 0, -1):
            np.multiply(q, tau, out=q)
            np.right_shift(q, shift, out=q)
            q += np.take(cols[k], index) * k
        np.right_shift(q, f.slope_preshift, out=q)
        np.multiply(q, f.tau_recip, out=q)
        np.right_shift(q, SLOPE_BITS + shift + w - f.slope_preshift, out=q)
        if outside is not None:
            q[np.atleast_1d(outside[0]) | np.atleast_1d(outside[1])] = 0
        return position, _unwrap(q, master_counts)

    def _lookup_one(self, m: int, with_slope: bool):
        """The same arithmetic for one master position with Python integers: no numpy overhead
        for a drive loop that asks once per cycle. Python's >> floors like asr, and the
        compiler's overflow proof makes unbounded ints agree with int64."""
        if not -(2**63) <= m < 2**63:
            raise InputError(f"master_counts {m} should fit int64")
        f = self.format
        if f.periodic:
            local = m % f.master_counts
        elif m < 0 or m >= f.master_counts:
            end = self._end_position(0 if m < 0 else -1)
            return (end, 0) if with_slope else end
        else:
            local = m
        if f.step_shift >= 0:
            i, tau = local >> f.step_shift, local & (f.step_counts - 1)
        else:
            i = local // f.step_counts
            tau = ((local - i * f.step_counts) * f.tau_recip) >> 32
        rows = self._scalar_rows()
        c = rows[i]
        n, shift, w = f.degree, f.tau_bits, f.work_bits
        r = c[n]
        for k in range(n - 1, -1, -1):
            r = c[k] + ((r * tau) >> shift)
        position = (r + ((1 << (w - 1)) if w else 0)) >> w
        if not with_slope:
            return position
        q = n * c[n]
        for k in range(n - 1, 0, -1):
            q = k * c[k] + ((q * tau) >> shift)
        slope = ((q >> f.slope_preshift) * f.tau_recip) >> (SLOPE_BITS + shift + w - f.slope_preshift)
        return position, slope

    def _scalar_rows(self) -> list:
        rows = getattr(self, "_rows_list", None)
        if rows is None:
            rows = list(zip(*(c.tolist() for c in self.coefficient_rows())))
            object.__setattr__(self, "_rows_list", rows)
        return rows

    def _end_position(self, index: int) -> int:
        qy = self.format.position_bits
        return (int(self.positions[index]) + ((1 << (qy - 1)) if qy else 0)) >> qy

    def slope(self, master_counts):
        """Slope of the interpolant: Q16 slave counts per master count (velocity feed-forward)."""
        return self.lookup(master_counts, with_slope=True)[1]

    # bytes -------------------------------------------------------------------------------------
    def _payload(self) -> bytes:
        parts = [self.positions.astype("<i4").tobytes()]
        if self.slopes is not None:
            parts.append(self.slopes.astype("<i4").tobytes())
        if self.curvatures is not None:
            parts.append(self.curvatures.astype("<i4").tobytes())
        return b"".join(parts)

    def to_bytes(self) -> bytes:
        """The binary blob of FORMAT.md: 64-byte header (with CRCs) + little-endian payload."""
        f = self.format
        payload = self._payload()
        header = _HEADER.pack(
            MAGIC, FORMAT_VERSION, HEADER_BYTES, f.degree, int(f.periodic), f.step_shift, f.tau_bits,
            f.work_bits, f.slope_bits, f.curvature_bits, f.slope_preshift, f.points, f.master_counts,
            f.step_counts, f.position_bits, bytes(3), f.tau_recip, len(payload), zlib.crc32(payload), bytes(12), 0,
        )
        header = header[:-4] + struct.pack("<I", zlib.crc32(header[:-4]))
        return header + payload

    @classmethod
    def from_bytes(cls, data) -> "CamTable":
        """Load and validate a blob; any malformed byte raises TableFormatError."""
        data = bytes(data)
        if len(data) < HEADER_BYTES:
            raise TableFormatError(f"blob length {len(data)} should be >= the {HEADER_BYTES}-byte header")
        fields = _HEADER.unpack_from(data)
        (magic, version, header_bytes, degree, flags, step_shift, tau_bits, work_bits, slope_bits,
         curvature_bits, preshift, points, master_counts, step_counts, position_bits, reserved, tau_recip,
         payload_bytes, payload_crc, reserved2, header_crc) = fields
        if magic != MAGIC:
            raise TableFormatError(f"blob magic {magic!r} should be {MAGIC!r}")
        if version != FORMAT_VERSION:
            raise TableFormatError(f"blob format_version {version} should be {FORMAT_VERSION}")
        if header_bytes != HEADER_BYTES:
            raise TableFormatError(f"blob header_bytes {header_bytes} should be {HEADER_BYTES}")
        if zlib.crc32(data[: HEADER_BYTES - 4]) != header_crc:
            raise TableFormatError(f"blob header_crc32 0x{header_crc:08x} does not match the header")
        if flags & ~1 or any(reserved) or any(reserved2):
            raise TableFormatError(f"blob flags 0x{flags:02x} / reserved bytes should be 0 except the periodic bit")
        fmt = TableFormat(degree, bool(flags & 1), points, master_counts, step_counts, step_shift, tau_bits,
                          work_bits, slope_bits, curvature_bits, preshift, tau_recip, position_bits)
        fmt.validate()
        if payload_bytes != fmt.payload_bytes:
            raise TableFormatError(f"blob payload_bytes {payload_bytes} should be {fmt.payload_bytes}")
        if len(data) != HEADER_BYTES + payload_bytes:
            raise TableFormatError(f"blob length {len(data)} should be {HEADER_BYTES + payload_bytes}")
        payload = data[HEADER_BYTES:]
        if zlib.crc32(payload) != payload_crc:
            raise TableFormatError(f"blob payload_crc32 0x{payload_crc:08x} does not match the payload")
        arrays = np.frombuffer(payload, dtype="<i4").reshape(fmt.values_per_point, points)
        positions, slopes = arrays[0], arrays[1] if degree >= 3 else None
        curvatures = arrays[2] if degree == 5 else None
        # The CRCs prove the bytes are intact, not that they came from the compiler: re-prove
        # that no intermediate can overflow, so every accepted table has exact results.
        ok, why, least_preshift = overflow_proof(degree, positions, slopes, curvatures, position_bits, slope_bits,
                                                 curvature_bits, work_bits, tau_bits, tau_recip)
        if not ok or preshift < least_preshift:
            reason = why or f"slope_preshift {preshift} should be >= {least_preshift}"
            raise TableFormatError(f"blob could overflow int64 in the lookup: {reason}")
        return cls(fmt, positions, slopes, curvatures)


def hermite_coefficients(degree, y, s=None, c=None) -> list:
    """The polynomial coefficients c_1..c_n of every interval (FORMAT.md step 4), from the point
    data scaled to the work format: positions ``y``, ``h*slopes`` ``s``, ``h^2*curvatures/2`` ``c``.

    The same integer combinations serve the exact int64 lookup and the float64 images the
    overflow proof bounds, so the two cannot drift apart.
    """
    d = y[1:] - y[:-1]
    if degree == 1:
        return [d]
    a0, a1 = s[:-1], s[1:]
    if degree == 3:
        return [a0, 3 * d - 2 * a0 - a1, a0 + a1 - 2 * d]
    b0, b1 = c[:-1], c[1:]
    return [a0, b0, 10 * d - 6 * a0 - 4 * a1 - 3 * b0 + b1, -15 * d + 8 * a0 + 7 * a1 + 3 * b0 - 2 * b1,
            6 * d - 3 * a0 - 3 * a1 - b0 + b1]


def _coefficients_float(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits, work_bits):
    """Float images (exact below 2^53, within a relative 1e-16 above) of Y0 * 2^(W-Qy) and the
    integer c_k."""
    y = positions.astype(np.float64) * 2.0 ** (work_bits - position_bits)
    s = None if slopes is None else slopes.astype(np.float64) * 2.0 ** (work_bits - slope_bits)
    c = None if curvatures is None else curvatures.astype(np.float64) * 2.0 ** (work_bits - curvature_bits)
    return y, hermite_coefficients(degree, y, s, c)


def overflow_proof(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits, work_bits, tau_bits,
           tau_recip):
    """Prove every intermediate of FORMAT.md steps 4-6 stays inside int64 and every output inside
    int32, for every interval and every tau < 2^F.

    Returns (ok, reason, slope_preshift): the smallest slope_preshift that keeps the slope path
    inside int64 (any larger one that keeps the final shift >= 0 works too)."""
    y, c = _coefficients_float(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits,
                               work_bits)
    tau_max = 2.0**tau_bits - 1
    n = degree
    if np.abs(y).max() * 2 >= _INT64_LIMIT:
        return False, f"position x 2^{work_bits - position_bits} exceeds int64", 0
    r = np.abs(c[n - 1])
    q = n * np.abs(c[n - 1])
    for k in range(n - 1, 0, -1):
        if r.max() * tau_max >= _INT64_LIMIT:
            return False, f"Horner product {r.max() * tau_max:.4g} exceeds int64 (work_bits {work_bits})", 0
        if q.max() * tau_max >= _INT64_LIMIT:
            return False, f"slope Horner product {q.max() * tau_max:.4g} exceeds int64 (work_bits {work_bits})", 0
        r = np.abs(c[k - 1]) + r + 1
        q = k * np.abs(c[k - 1]) + q + 1
    if r.max() * tau_max >= _INT64_LIMIT:
        return False, f"final product {r.max() * tau_max:.4g} exceeds int64 (work_bits {work_bits})", 0
    if (np.abs(y[:-1]) + r + 2.0**work_bits).max() >= _INT64_LIMIT:
        return False, f"final sum exceeds int64 (work_bits {work_bits})", 0
    # The interpolant on [0, 1] lies in the hull of its Bernstein coefficients; Horner floors and
    # the final rounding move the result by less than one more count.
    reach = np.zeros_like(y[:-1])
    for j in range(n + 1):
        b = y[:-1].copy()
        for k in range(1, j + 1):
            b += math.comb(j, k) / math.comb(n, k) * c[k - 1]
        reach = np.maximum(reach, np.abs(b))
    reach = reach / 2.0**work_bits + n * 2.0**-work_bits + 1
    if reach.max() > _INT32_MAX:
        return False, f"interpolated position may reach {reach.max():.0f} counts, past int32", 0
    q_max = float(q.max())
    preshift = max(0, SLOPE_BITS + tau_bits + work_bits - 63)  # keep the final shift <= 63
    while (q_max / 2.0**preshift + 1) * tau_recip >= _INT64_LIMIT:
        preshift += 1
    final = SLOPE_BITS + tau_bits + work_bits - preshift
    if final < 0:
        return False, f"slope shift {final} would be negative", 0
    slope_peak = (q_max / 2.0**preshift + 1) * tau_recip / 2.0**final + 1
    if slope_peak > _INT32_MAX:
        return False, f"slope may reach {slope_peak:.4g} (Q16 counts per count), past int32", 0
    return True, "", preshift


def _as_counts(master_counts) -> np.ndarray:
    if isinstance(master_counts, (bool, np.bool_)):
        raise InputError(f"master_counts {master_counts!r} should be an integer")
    array = np.asarray(master_counts)
    if array.dtype.kind not in "iu":
        if array.dtype == object:
            try:
                array = array.astype(np.int64)
            except OverflowError:
                raise InputError("master_counts should fit int64") from None
        else:
            raise InputError(f"master_counts of dtype {array.dtype} should be integers")
    if array.dtype == np.uint64 and array.size and array.max() > np.iinfo(np.int64).max:
        raise InputError("master_counts should fit int64")
    return array.astype(np.int64, copy=False)


def _unwrap(values, original):
    return int(values[0]) if np.ndim(original) == 0 else values
