"""CamTable: an immutable fixed-point cam table and its integer lookup.

The lookup is the exact mirror of the C reference runtime (``firmware_tables/ecam_table.c``);
both follow ``firmware_tables/FORMAT.md`` step by step: integers only, int64 intermediates,
every intermediate shift floors, the final shift rounds half up.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from .certificate import Certificate
from .errors import TableFormatError
from .validate import fail

__all__ = ["TableFormat", "CamTable", "LOADER_STATUS", "loader_proof", "narrow_horner", "INTERPOLATIONS", "KINDS", "SLOPE_BITS", "HEADER_BYTES", "FORMAT_VERSION", "FORMAT_VERSIONS",
           "MAGIC", "MAX_NET_DENOMINATOR", "MAX_RAMP"]

KINDS = {"linear": 1, "cubic": 3, "quintic": 5}
# Every name a user may ask for: a kind, or "auto" (the smallest table of any kind within a tolerance).
INTERPOLATIONS = (*KINDS, "auto")
_KIND_NAMES = {v: k for k, v in KINDS.items()}
SLOPE_BITS = 16
HEADER_BYTES = 64
# Version 2 adds the net stroke per period (header bytes 48..59). A table without one is written
# as version 1, byte for byte as before, so every loader of version 1 still reads it. Version 3 is
# version 2 with the stored data relative to the net stroke's ramp (S counts per master count,
# S = floor(N / (D M))), so that a large stroke keeps its positions' fraction bits in int32.
FORMAT_VERSION = 3
FORMAT_VERSIONS = (1, 2, 3)
# Version 3's ramp: |S| 2^16 (its share of the Q16 slope) stays inside int32.
MAX_RAMP = 2**15 - 1
MAGIC = b"ECAM"
# The net stroke is the exact rational net_stroke_num / net_stroke_den counts per period.
MAX_NET_DENOMINATOR = 2**32 - 1
_NET = struct.Struct("<qI")  # header bytes 48..59 of version 2
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
    net_stroke_num: int = 0
    net_stroke_den: int = 1
    ramp: bool = False

    @property
    def interp(self) -> str:
        """The interpolation kind of ``degree``: ``"linear"``, ``"cubic"`` or ``"quintic"``."""
        return _KIND_NAMES[self.degree]

    @property
    def net_stroke(self) -> Fraction:
        """Slave counts added per master period: exactly ``net_stroke_num / net_stroke_den``."""
        return Fraction(self.net_stroke_num, self.net_stroke_den)

    @property
    def version(self) -> int:
        """The blob format version this table is written in: 1 without a net stroke, 2 with one,
        3 with one and the stored data relative to its ramp (:attr:`ramp`)."""
        if self.ramp:
            return 3
        return 1 if self.net_stroke_num == 0 else 2

    @property
    def ramp_slope(self) -> int:
        """S, the ramp of a version-3 table in whole slave counts per master count:
        ``floor(N / (D M))`` for the net stroke N/D per period of M master counts (0 unless
        :attr:`ramp`). The lookup adds ``S * m_local`` to the position and ``S * 2^16`` to the
        slope (FORMAT.md step 8)."""
        if not self.ramp:
            return 0
        return self.net_stroke_num // (self.net_stroke_den * self.master_counts)

    @property
    def values_per_point(self) -> int:
        """int32 values stored per point: position, then slope (cubic), then curvature (quintic)."""
        return (self.degree + 1) // 2

    @property
    def payload_bytes(self) -> int:
        """Bytes after the header: ``points x 4 x values_per_point``."""
        return self.points * 4 * self.values_per_point

    def validate(self) -> None:
        """Raise TableFormatError naming the first field that breaks its rule.

        The rules and their order are the blob loader's (:data:`FIELD_RULES`, FORMAT.md
        "Loader"), without the rules about bytes only a blob has (flags, reserved bytes, payload
        size); the error's ``status`` is the C loader's status name for the rule.
        """
        failure = broken_field_rule(self)
        if failure is not None:
            error = TableFormatError(failure[1])
            error.status = failure[0]
            raise error


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

    # equality ----------------------------------------------------------------------------------
    def __eq__(self, other):
        """Tables are equal when they hold the same format and the same stored values, so they
        write the same blob and look up the same everywhere: ``CamTable.from_bytes(t.to_bytes())
        == t``. The certificate (what the compiler proved and measured about the table, absent
        from a blob) is not compared."""
        if not isinstance(other, CamTable):
            return NotImplemented
        return self.format == other.format and all(
            (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
            for a, b in ((self.positions, other.positions), (self.slopes, other.slopes),
                         (self.curvatures, other.curvatures)))

    def __hash__(self):
        return hash((self.format, self.crc32))

    # convenience -----------------------------------------------------------------------------
    @property
    def report(self) -> dict:
        """The certificate joined with the table's facts: the JSON contract of ``ecam compile
        --json`` (``interp``, ``points``, ``bytes``, ``crc32``, ``max_error_counts``,
        ``max_error_units``, ``predicted_error_units``, ...).

        Returns
        -------
        dict
            A new dictionary on every access, recomputed from :attr:`certificate` and the table
            (the CRC included): keep it rather than reading it in a loop. ``{}`` for a table
            loaded from bytes, which has no certificate.
        """
        return {} if self.certificate is None else self.certificate.report(self)

    @property
    def interp(self) -> str:
        """The interpolation kind: ``"linear"``, ``"cubic"`` or ``"quintic"``."""
        return self.format.interp

    @property
    def points(self) -> int:
        """Stored points (intervals + 1), at master counts ``i * step_counts``."""
        return self.format.points

    @property
    def master_counts(self) -> int:
        """The master period in counts (the table's span for a cam that is not periodic)."""
        return self.format.master_counts

    @property
    def periodic(self) -> bool:
        """True when the lookup wraps the master modulo :attr:`master_counts`; False when it holds
        the end positions outside ``[0, master_counts)``."""
        return self.format.periodic

    @property
    def net_stroke(self) -> Fraction:
        """Slave counts the lookup adds per master period passed (exact; 0 for most cams)."""
        return self.format.net_stroke

    @property
    def format_version(self) -> int:
        """The blob format version :meth:`to_bytes` writes: 1, 2 for a net stroke, 3 for one stored relative to its ramp."""
        return self.format.version

    @property
    def crc32(self) -> int:
        """CRC-32 (zlib's, as the blob header stores it) of the little-endian payload."""
        return zlib.crc32(self._payload())

    @property
    def nbytes(self) -> int:
        """Size of the blob :meth:`to_bytes` writes: the 64-byte header plus the payload."""
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
            A table with a net stroke ``N/D`` counts per period (:attr:`net_stroke`) adds, for
            the ``k = floor(m / M)`` whole periods passed (negative below 0),
            ``floor((k N + floor(D/2)) / D)``: ``k N/D`` rounded to nearest, ties up, in exact
            integers, so nothing accumulates however far the master goes (FORMAT.md, step 7).
            The result is exact while it fits int64, and taken modulo 2^64 beyond (the C
            runtime's 64-bit variant; its int32 position is the low 32 bits, as a CiA 402
            position rolls over). The slope has no net term: it is periodic and continuous
            across the wrap wherever the cam's velocity is.
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
        ramp = f.ramp_slope
        if outside is not None:
            below, above = np.atleast_1d(outside[0]), np.atleast_1d(outside[1])
            position[below] = self._end_position(0)
            position[above] = self._end_position(-1)
        elif f.net_stroke_num:
            turns = np.atleast_1d(np.floor_divide(_as_counts(master_counts), f.master_counts))
            with np.errstate(over="ignore"):
                position += net_stroke_term(turns, f.net_stroke_num, f.net_stroke_den)
                if ramp:  # step 8: S m_local, exact (|S| < 2^15, m_local < 2^31)
                    position += np.int64(ramp) * np.atleast_1d(np.mod(_as_counts(master_counts), f.master_counts))
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
        if ramp:
            q += ramp << SLOPE_BITS
        return position, _unwrap(q, master_counts)

    def _lookup_one(self, m: int, with_slope: bool):
        """The same arithmetic for one master position with Python integers: no numpy overhead
        for a drive loop that asks once per cycle. Python's >> floors like asr, and the
        compiler's overflow proof makes unbounded ints agree with int64."""
        if not -(2**63) <= m < 2**63:
            raise fail("master_counts", m, _INT64_RANGE)
        f = self.format
        if f.periodic:
            turns, local = divmod(m, f.master_counts)
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
        if f.net_stroke_num:  # exact in Python integers, then modulo 2^64 as the vector path
            position += (turns * f.net_stroke_num + f.net_stroke_den // 2) // f.net_stroke_den
            position += f.ramp_slope * local
            position = ((position + 2**63) % 2**64) - 2**63
        if not with_slope:
            return position
        q = n * c[n]
        for k in range(n - 1, 0, -1):
            q = k * c[k] + ((q * tau) >> shift)
        slope = ((q >> f.slope_preshift) * f.tau_recip) >> (SLOPE_BITS + shift + w - f.slope_preshift)
        return position, slope + (f.ramp_slope << SLOPE_BITS)

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
        # Version 1 (bytes 48..59 zero) unless the table has a net stroke: versions 2 and 3 store it there.
        net = bytes(12) if f.version == 1 else _NET.pack(f.net_stroke_num, f.net_stroke_den)
        header = _HEADER.pack(
            MAGIC, f.version, HEADER_BYTES, f.degree, int(f.periodic), f.step_shift, f.tau_bits,
            f.work_bits, f.slope_bits, f.curvature_bits, f.slope_preshift, f.points, f.master_counts,
            f.step_counts, f.position_bits, bytes(3), f.tau_recip, len(payload), zlib.crc32(payload), net, 0,
        )
        header = header[:-4] + struct.pack("<I", zlib.crc32(header[:-4]))
        return header + payload

    @classmethod
    def from_bytes(cls, data) -> "CamTable":
        """Load and validate a blob; any malformed byte raises TableFormatError.

        The checks, their order and their decisions are exactly those of the C loader
        (``ecam_table_init``, FORMAT.md "Loader"): the envelope, every field rule, the length, the
        payload CRC, then the overflow proof in exact integers for the header's own fields. So
        both accept the same blobs, and on every accepted blob both lookups agree bit for bit.
        Each message names the field, the value and the rule, and ends with the C status name.
        """
        data = bytes(data)
        if len(data) < HEADER_BYTES:
            _reject("ECAM_E_SHORT", f"blob length {len(data)} should be >= the {HEADER_BYTES}-byte header")
        fields = _HEADER.unpack_from(data)
        (magic, version, header_bytes, degree, flags, step_shift, tau_bits, work_bits, slope_bits,
         curvature_bits, preshift, points, master_counts, step_counts, position_bits, reserved, tau_recip,
         payload_bytes, payload_crc, reserved2, header_crc) = fields
        if magic != MAGIC:
            _reject("ECAM_E_MAGIC", f"blob magic {magic!r} should be {MAGIC!r}")
        if version not in FORMAT_VERSIONS:
            _reject("ECAM_E_VERSION", f"blob format_version {version} should be 1, 2 or 3")
        if header_bytes != HEADER_BYTES:
            _reject("ECAM_E_HEADER_SIZE", f"blob header_bytes {header_bytes} should be {HEADER_BYTES}")
        if zlib.crc32(data[: HEADER_BYTES - 4]) != header_crc:
            _reject("ECAM_E_HEADER_CRC", f"blob header_crc32 0x{header_crc:08x} does not match the header")
        net_num, net_den = 0, 1
        if version >= 2:  # bytes 48..59 hold the net stroke; only 29..31 stay reserved
            (net_num, net_den), reserved2 = _NET.unpack(reserved2), b""
        fmt = TableFormat(degree, bool(flags & 1), points, master_counts, step_counts, step_shift, tau_bits,
                          work_bits, slope_bits, curvature_bits, preshift, tau_recip, position_bits, net_num, net_den,
                          version == 3)
        failure = broken_field_rule(fmt, BlobBytes(flags, reserved + reserved2, payload_bytes))
        if failure is not None:
            _reject(failure[0], f"blob {failure[1]}")
        if len(data) != HEADER_BYTES + payload_bytes:
            _reject("ECAM_E_LENGTH", f"blob length {len(data)} should be {HEADER_BYTES + payload_bytes}")
        payload = memoryview(data)[HEADER_BYTES:]  # no copy of a large payload
        if zlib.crc32(payload) != payload_crc:
            _reject("ECAM_E_PAYLOAD_CRC", f"blob payload_crc32 0x{payload_crc:08x} does not match the payload")
        arrays = np.frombuffer(payload, dtype="<i4").reshape(fmt.values_per_point, points)
        positions, slopes = arrays[0], arrays[1] if degree >= 3 else None
        curvatures = arrays[2] if degree == 5 else None
        # The CRCs prove the bytes are intact, not that they came from the compiler: prove, for the
        # header's own shifts, that no intermediate can leave int64 and no output int32.
        failure = loader_proof(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits,
                               work_bits, tau_bits, tau_recip, preshift, abs(fmt.ramp_slope) << SLOPE_BITS)
        if failure is not None:
            _reject(*failure)
        return cls(fmt, positions, slopes, curvatures)


# The C loader's status names (firmware_tables/ecam_table.h), for messages and the parity tests.
LOADER_STATUS = {
    "ECAM_E_SHORT": -1, "ECAM_E_MAGIC": -2, "ECAM_E_VERSION": -3, "ECAM_E_HEADER_SIZE": -4,
    "ECAM_E_HEADER_CRC": -5, "ECAM_E_LENGTH": -7, "ECAM_E_PAYLOAD_CRC": -8, "ECAM_E_DEGREE": -10,
    "ECAM_E_FLAGS": -11, "ECAM_E_RESERVED": -12, "ECAM_E_POINTS": -13, "ECAM_E_MASTER_COUNTS": -14,
    "ECAM_E_STEP_COUNTS": -15, "ECAM_E_STEP_SHIFT": -16, "ECAM_E_TAU_BITS": -17, "ECAM_E_TAU_RECIP": -18,
    "ECAM_E_POSITION_BITS": -19, "ECAM_E_WORK_BITS": -20, "ECAM_E_SLOPE_BITS": -21,
    "ECAM_E_CURVATURE_BITS": -22, "ECAM_E_SLOPE_PRESHIFT": -23, "ECAM_E_PAYLOAD_BYTES": -24,
    "ECAM_E_POINT_RANGE": -25, "ECAM_E_HORNER_RANGE": -26, "ECAM_E_SUM_RANGE": -27,
    "ECAM_E_POSITION_RANGE": -28, "ECAM_E_SLOPE_HORNER_RANGE": -29, "ECAM_E_SLOPE_PRODUCT": -30,
    "ECAM_E_SLOPE_RANGE": -31, "ECAM_E_NET_STROKE": -34, "ECAM_E_RAMP": -36,
}  # fmt: skip


def _reject(status: str, message: str):
    """Raise the loader's TableFormatError; ``status`` (the C code's name) is also its attribute."""
    error = TableFormatError(f"{message} ({status})")
    error.status = status
    raise error


class BlobBytes(NamedTuple):
    """The header bytes of a blob that a :class:`TableFormat` has no field for."""

    flags: int
    reserved: bytes  # 29..31, and 48..59 in version 1
    payload_bytes: int


class FieldRule(NamedTuple):
    """One field rule of FORMAT.md: ``broken(format, blob)`` is true when the fields break it,
    ``says(format, blob)`` what the field holds and what it should be (one line, no status)."""

    status: str  # the C loader's status name (LOADER_STATUS)
    broken: Callable[[TableFormat, BlobBytes | None], bool]
    says: Callable[[TableFormat, BlobBytes | None], str]
    blob_only: bool = False  # about bytes a TableFormat does not hold


def _pow2(h: int) -> bool:
    return h & (h - 1) == 0


def _shift_of(h: int) -> int:
    """step_shift for step_counts ``h``: log2 h for a power of two, else -1."""
    return h.bit_length() - 1 if _pow2(h) else -1


def _tau_bits_needed(h: int) -> int:
    return (h - 1).bit_length()  # ceil(log2 h)


def _tau_bits_expected(h: int) -> str:
    return f"{_shift_of(h)}" if _pow2(h) else f"in {_tau_bits_needed(h)}..30"


def _scaled_bits(f: TableFormat) -> int:
    return SLOPE_BITS + f.tau_bits + f.work_bits


#: The field rules of FORMAT.md in the C loader's order (ecam_table_init), each with its status:
#: the one statement of them. :meth:`CamTable.from_bytes` applies all of them, with the blob's own
#: bytes; :meth:`TableFormat.validate` those about the format's fields. The bounds are written so
#: that the values a Python caller can give (negative, or past a header field's width) break them
#: too; a blob's header types cannot hold those.
FIELD_RULES = (
    FieldRule("ECAM_E_DEGREE", lambda f, b: f.degree not in _KIND_NAMES,
              lambda f, b: f"degree {f.degree} should be 1, 3 or 5"),
    FieldRule("ECAM_E_FLAGS", lambda f, b: b.flags & ~1,
              lambda f, b: f"flags 0x{b.flags:02x} should have no bit but bit 0 (periodic)", blob_only=True),
    FieldRule("ECAM_E_RESERVED", lambda f, b: any(b.reserved),
              lambda f, b: "reserved bytes 29..31 (and 48..59 in version 1) should be 0", blob_only=True),
    FieldRule("ECAM_E_POINTS", lambda f, b: not 2 <= f.points <= 2**32 - 1,
              lambda f, b: f"points {f.points} should be {'>= 2' if f.points < 2 else '<= 2^32-1'}"),
    FieldRule("ECAM_E_MASTER_COUNTS", lambda f, b: not 2 <= f.master_counts <= MAX_MASTER_COUNTS,
              lambda f, b: f"master_counts {f.master_counts} should be in 2..{MAX_MASTER_COUNTS}"),
    FieldRule("ECAM_E_STEP_COUNTS",
              lambda f, b: (not 1 <= f.step_counts <= MAX_STEP_COUNTS
                            or (f.points - 1) * f.step_counts != f.master_counts),
              lambda f, b: f"step_counts {f.step_counts} should be in 1..{MAX_STEP_COUNTS} with (points - 1) * "
                           f"step_counts = master_counts {f.master_counts} (points {f.points})"),
    FieldRule("ECAM_E_STEP_SHIFT", lambda f, b: f.step_shift != _shift_of(f.step_counts),
              lambda f, b: f"step_shift {f.step_shift} should be {_shift_of(f.step_counts)} for step_counts "
                           f"{f.step_counts}"),
    FieldRule("ECAM_E_TAU_BITS",
              lambda f, b: (f.tau_bits > 30 or f.tau_bits < _tau_bits_needed(f.step_counts)
                            or (_pow2(f.step_counts) and f.tau_bits != _shift_of(f.step_counts))),
              lambda f, b: f"tau_bits {f.tau_bits} should be {_tau_bits_expected(f.step_counts)} for step_counts "
                           f"{f.step_counts}"),
    FieldRule("ECAM_E_TAU_RECIP", lambda f, b: f.tau_recip != -(-(1 << (32 + f.tau_bits)) // f.step_counts),
              lambda f, b: f"tau_recip {f.tau_recip} should be ceil(2^(32+tau_bits)/step_counts)"),
    FieldRule("ECAM_E_POSITION_BITS", lambda f, b: not 0 <= f.position_bits <= 30,
              lambda f, b: f"position_bits {f.position_bits} should be in 0..30"),
    FieldRule("ECAM_E_WORK_BITS",
              lambda f, b: (not f.position_bits <= f.work_bits <= MAX_WORK_BITS
                            or (f.degree == 1 and f.work_bits != f.position_bits)),
              lambda f, b: f"work_bits {f.work_bits} should be "
                           + (f"position_bits = {f.position_bits} for linear" if f.degree == 1
                              else f"in {f.position_bits}..{MAX_WORK_BITS}")),
    FieldRule("ECAM_E_SLOPE_BITS",
              lambda f, b: not 0 <= f.slope_bits <= f.work_bits or (f.degree == 1 and f.slope_bits),
              lambda f, b: f"slope_bits {f.slope_bits} should be "
                           f"{'0 for linear' if f.degree == 1 else f'in 0..work_bits = {f.work_bits}'}"),
    FieldRule("ECAM_E_CURVATURE_BITS",
              lambda f, b: not 0 <= f.curvature_bits <= f.work_bits or (f.degree != 5 and f.curvature_bits),
              lambda f, b: f"curvature_bits {f.curvature_bits} should be "
                           f"{'0 unless quintic' if f.degree != 5 else f'in 0..work_bits = {f.work_bits}'}"),
    FieldRule("ECAM_E_SLOPE_PRESHIFT",
              lambda f, b: f.slope_preshift < 0 or not 0 <= _scaled_bits(f) - f.slope_preshift <= 63,
              lambda f, b: f"slope_preshift {f.slope_preshift} should be in {max(0, _scaled_bits(f) - 63)}.."
                           f"{_scaled_bits(f)} (16 + tau_bits + work_bits - slope_preshift in 0..63)"),
    FieldRule("ECAM_E_PAYLOAD_BYTES", lambda f, b: b.payload_bytes != f.payload_bytes,
              lambda f, b: f"payload_bytes {b.payload_bytes} should be {f.payload_bytes}", blob_only=True),
    FieldRule("ECAM_E_NET_STROKE", lambda f, b: bool(_net_stroke_rule(f.periodic, f.net_stroke_num, f.net_stroke_den)),
              lambda f, b: f"net stroke {f.net_stroke_num}/{f.net_stroke_den} counts per period should be "
                           f"{_net_stroke_rule(f.periodic, f.net_stroke_num, f.net_stroke_den)}"),
    FieldRule("ECAM_E_RAMP", lambda f, b: f.ramp and (f.net_stroke_num == 0 or abs(f.ramp_slope) > MAX_RAMP),
              lambda f, b: f"ramp {f.ramp_slope} counts per master count (version 3) should be that of a net stroke "
                           f"(not 0/1), within +-{MAX_RAMP}"),
)


def broken_field_rule(fmt: TableFormat, blob: BlobBytes | None = None) -> tuple[str, str] | None:
    """(status, message) of the first rule of :data:`FIELD_RULES` that ``fmt`` (and the blob's own
    bytes, if given; else the rules about them are skipped) breaks, or None."""
    for rule in FIELD_RULES:
        if rule.blob_only and blob is None:
            continue
        if rule.broken(fmt, blob):
            return rule.status, rule.says(fmt, blob)
    return None


# Bernstein coefficients of step 5's polynomial on [0, 1], times Dn = lcm C(n, k):
# Dn * B_j = Dn * Y0 + sum_k weight[j][k] * c_k with weight = C(j, k) * Dn / C(n, k).
_BERNSTEIN = {
    1: (1, ((), (1,))),
    3: (3, ((), (1,), (2, 1), (3, 3, 3))),
    5: (10, ((), (2,), (4, 1), (6, 3, 1), (8, 6, 4, 2), (10, 10, 10, 10, 10))),
}


#: Intervals the loader's proof handles at once: its memory stays a few MB whatever the table.
PROOF_CHUNK = 1 << 16


def loader_proof(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits, work_bits,
                 tau_bits, tau_recip, slope_preshift, slope_margin=0):
    """The loader's overflow proof (FORMAT.md "Overflow proof"), in exact integers: None when every
    lookup of the table keeps its intermediates inside int64 and both outputs inside
    -(2^31 - 1)..2^31 - 1, else (status, message) of the first failing rule, interval by interval,
    rule by rule, exactly as the C loader decides. The compiler's float proof (:func:`overflow_proof`)
    implies this one.

    Linear in the points and lean in memory: the intervals are taken :data:`PROOF_CHUNK` at a time;
    in each, a float64 screen passes every interval whose every bound, rounding error included,
    lies clearly inside its limit (every table the compiler writes), and only the others are
    decided in exact integers. An interval the screen passes passes every rule exactly, so the
    first failure found in exact integers, in interval order, is the C loader's.

    ``slope_margin`` is |S| 2^16, the share of a version-3 ramp in the slope: the slope of the
    stored data stays within (2^31 - 1) - slope_margin (rule -31).
    """
    args = (degree, position_bits, slope_bits, curvature_bits, work_bits, tau_bits, tau_recip, slope_preshift,
            slope_margin)
    intervals = len(positions) - 1
    for start in range(0, intervals, PROOF_CHUNK):
        stop = min(start + PROOF_CHUNK, intervals)
        window = slice(start, stop + 1)
        arrays = [None if a is None else np.asarray(a[window]) for a in (positions, slopes, curvatures)]
        doubtful = np.flatnonzero(~_screen_passes(*arrays, *args))
        if doubtful.size:
            failure = _exact_proof(*arrays, doubtful, *args)
            if failure is not None:
                interval, status, what = failure
                return status, f"blob could overflow in the lookup: interval {start + interval}: {what}"
    return None


_SCREEN_ERROR = 2.0**-40  # relative rounding error allowed for each float bound (about 2^-48 at most)


def _screen_passes(positions, slopes, curvatures, degree, position_bits, slope_bits, curvature_bits, work_bits,
                   tau_bits, tau_recip, slope_preshift, slope_margin=0) -> np.ndarray:
    """Per interval, True when float64 bounds prove every rule of the overflow proof with room to
    spare. Stored words times powers of two are exact in float64; every derived value carries a
    bound of its rounding error (relative to the sum of the magnitudes it adds), so each upper
    bound below is above the exact value it bounds."""
    n = degree
    inflate = 1 + _SCREEN_ERROR

    def scaled(array, bits):
        return None if array is None else array.astype(np.float64) * 2.0 ** (work_bits - bits)

    y = scaled(positions, position_bits)
    a, b = scaled(slopes, slope_bits), scaled(curvatures, curvature_bits)
    c = hermite_coefficients(n, y, a, b)
    # the same combinations of the magnitudes: each c_k's rounding error is below 2^-50 of it
    magnitude = hermite_magnitudes(n, np.abs(y), None if a is None else np.abs(a), None if b is None else np.abs(b))
    upper = [np.abs(ck) + m * _SCREEN_ERROR for ck, m in zip(c, magnitude)]
    y0, y1 = y[:-1], y[1:]
    two63 = 2.0**63
    tau_max = 2.0**tau_bits - 1
    ok = (np.abs(y0) < 2.0**62) & (np.abs(y1) < 2.0**62)
    r = upper[n - 1]
    ok &= r * tau_max * inflate < two63
    for k in range(n - 1, 0, -1):
        r = (upper[k - 1] + r + 1) * inflate
        ok &= r * tau_max * inflate < two63
    ok &= (np.abs(y0) + r + 2.0**work_bits) * inflate < two63
    scale, weights = _BERNSTEIN[n]
    reach_limit = scale * (2.0**31 - 1) * 2.0**work_bits
    for row in weights:
        value = scale * y0
        spread = scale * np.abs(y0)
        for k, weight in enumerate(row, start=1):
            value = value + weight * c[k - 1]
            spread = spread + weight * (magnitude[k - 1] + upper[k - 1])
        ok &= (np.abs(value) + spread * _SCREEN_ERROR + scale * n) * inflate < reach_limit
    q = n * upper[n - 1]
    for k in range(n - 1, 0, -1):
        ok &= q * tau_max * inflate < two63
        q = (k * upper[k - 1] + q + 1) * inflate
    ok &= q < two63
    s = q / 2.0**slope_preshift + 1  # above ceil(q_1 / 2^P)
    product = s * float(tau_recip) * inflate
    ok &= product < two63
    ok &= product < (2.0**31 - 1 - slope_margin) * 2.0 ** (SLOPE_BITS + tau_bits + work_bits - slope_preshift)
    return ok


def _exact_proof(positions, slopes, curvatures, intervals, degree, position_bits, slope_bits, curvature_bits,
                 work_bits, tau_bits, tau_recip, slope_preshift, slope_margin=0):
    """The proof in exact integers for the listed intervals (indices into the given points, in
    ascending order): (interval, status, what it checks) of the first failure, or None."""
    n = degree
    two63 = 1 << 63
    tau_max = (1 << tau_bits) - 1

    def exact(array, bits):
        if array is None:
            return None
        ends = np.stack([array[intervals], array[intervals + 1]])  # row 0: point i, row 1: point i + 1
        return np.array([[int(v) << (work_bits - bits) for v in row] for row in ends.tolist()], dtype=object)

    y = exact(positions, position_bits)
    c = [ck[0] for ck in hermite_coefficients(degree, y, exact(slopes, slope_bits), exact(curvatures, curvature_bits))]
    y0, y1 = y[0], y[1]
    magnitude = [np.abs(ck) for ck in c]  # |c_1| .. |c_n|
    failures = {}  # status -> (bool per interval, what it checks)
    point_limit = 1 << 62
    failures["ECAM_E_POINT_RANGE"] = ((np.abs(y0) >= point_limit) | (np.abs(y1) >= point_limit),
                                      f"|position x 2^{work_bits - position_bits}| should be < 2^62")
    bad = np.zeros(y0.shape, dtype=bool)
    r = magnitude[n - 1]
    bad |= r * tau_max >= two63
    for k in range(n - 1, 0, -1):
        r = magnitude[k - 1] + r + 1
        bad |= r * tau_max >= two63
    failures["ECAM_E_HORNER_RANGE"] = (bad, f"every position Horner product (x tau <= {tau_max}) should be < 2^63")
    failures["ECAM_E_SUM_RANGE"] = (np.abs(y0) + r + (1 << work_bits) >= two63,
                                    "the final position sum should stay < 2^63")
    scale, weights = _BERNSTEIN[n]
    reach_limit = scale * (2**31 - 1) << work_bits
    bad = np.zeros(y0.shape, dtype=bool)
    for row in weights:
        b = scale * y0
        for k, weight in enumerate(row, start=1):
            b = b + weight * c[k - 1]
        bad |= np.abs(b) + scale * n > reach_limit
    failures["ECAM_E_POSITION_RANGE"] = (bad, "the position should stay within -(2^31 - 1)..2^31 - 1")
    bad = np.zeros(y0.shape, dtype=bool)
    q = n * magnitude[n - 1]
    for k in range(n - 1, 0, -1):
        bad |= q * tau_max >= two63
        q = k * magnitude[k - 1] + q + 1
    bad |= q >= two63
    failures["ECAM_E_SLOPE_HORNER_RANGE"] = (bad, f"every slope Horner product (x tau <= {tau_max}) and sum "
                                                  "should be < 2^63")
    out_shift = SLOPE_BITS + tau_bits + work_bits - slope_preshift
    s = -((-q) >> slope_preshift)  # ceil(q / 2^P): the largest |asr(q, P)|
    product = s * tau_recip
    failures["ECAM_E_SLOPE_PRODUCT"] = (product >= two63, f"asr(q, slope_preshift {slope_preshift}) x tau_recip "
                                                          f"{tau_recip} should be < 2^63")
    failures["ECAM_E_SLOPE_RANGE"] = (product > (2**31 - 1 - slope_margin) << out_shift,
                                      f"the slope should stay within -(2^31 - 1)..2^31 - 1 at slope_preshift "
                                      f"{slope_preshift}" + (f" with the ramp's {slope_margin}" if slope_margin else ""))
    first = {status: np.flatnonzero(np.asarray(bad, dtype=bool)) for status, (bad, _) in failures.items()}
    found = [(int(intervals[where[0]]), order, status) for order, (status, where) in enumerate(first.items())
             if where.size]
    if not found:
        return None
    interval, _, status = min(found)
    return interval, status, failures[status][1]


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


def narrow_horner(table: "CamTable") -> bool:
    """True when the expanded form of ``table`` runs in 32-bit words (FORMAT.md "Expanded form"):
    with c0 = Y0 2^(W-Qy) + half and c1..cn of step 4 for every interval, r_n = |c_n|,
    r_k = |c_k| + r_(k+1) + 1 < 2^30 for k = n..1, |c0| + r_1 + 1 < 2^31, and W <= 30; the C
    runtime's ``ecam_poly_init`` decides the same and then picks its narrow kernels."""
    f = table.format
    if f.work_bits > 30:
        return False
    rows = [np.abs(row).astype(np.float64) for row in table.coefficient_rows()]  # exact below 2^53
    half = float(1 << (f.work_bits - 1)) if f.work_bits else 0.0
    r = rows[f.degree]
    ok = bool((r < 2.0**30).all())
    for k in range(f.degree - 1, 0, -1):
        r = r + rows[k] + 1
        ok = ok and bool((r < 2.0**30).all())
    c0 = np.abs(table.coefficient_rows()[0].astype(np.float64) + half)
    return ok and bool((c0 + r + 1 < 2.0**31).all())


def hermite_magnitudes(degree, y, s=None, c=None) -> list:
    """The combinations of :func:`hermite_coefficients` with every weight made positive, on
    magnitudes ``|y|``, ``|s|``, ``|c|``: a bound of each |c_k| and the scale of its float
    rounding error."""
    d = y[1:] + y[:-1]
    if degree == 1:
        return [d]
    a0, a1 = s[:-1], s[1:]
    if degree == 3:
        return [a0, 3 * d + 2 * a0 + a1, a0 + a1 + 2 * d]
    b0, b1 = c[:-1], c[1:]
    return [a0, b0, 10 * d + 6 * a0 + 4 * a1 + 3 * b0 + b1, 15 * d + 8 * a0 + 7 * a1 + 3 * b0 + 2 * b1,
            6 * d + 3 * a0 + 3 * a1 + b0 + b1]


def _coefficients_float(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits, work_bits):
    """Float images (exact below 2^53, within a relative 1e-16 above) of Y0 * 2^(W-Qy) and the
    integer c_k."""
    y = positions.astype(np.float64) * 2.0 ** (work_bits - position_bits)
    s = None if slopes is None else slopes.astype(np.float64) * 2.0 ** (work_bits - slope_bits)
    c = None if curvatures is None else curvatures.astype(np.float64) * 2.0 ** (work_bits - curvature_bits)
    return y, hermite_coefficients(degree, y, s, c)


def overflow_proof(degree, positions, slopes, curvatures, position_bits, slope_bits, curvature_bits, work_bits, tau_bits,
           tau_recip, slope_margin=0):
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
    if q_max >= _INT64_LIMIT:
        return False, f"slope Horner sum {q_max:.4g} exceeds int64 (work_bits {work_bits})", 0
    preshift = max(0, SLOPE_BITS + tau_bits + work_bits - 63)  # keep the final shift <= 63
    while (q_max / 2.0**preshift + 1) * tau_recip >= _INT64_LIMIT:
        preshift += 1
    final = SLOPE_BITS + tau_bits + work_bits - preshift
    if final < 0:
        return False, f"slope shift {final} would be negative", 0
    slope_peak = (q_max / 2.0**preshift + 1) * tau_recip / 2.0**final + 1 + slope_margin
    if slope_peak > _INT32_MAX:
        return False, f"slope may reach {slope_peak:.4g} (Q16 counts per count), past int32", 0
    return True, "", preshift


def divisors(n: int) -> list[int]:
    """Every divisor of ``n`` >= 1, ascending: the interval counts a table of ``n`` master counts
    can have (``(points - 1) * step_counts == master_counts``)."""
    small, large = [], []
    d = 1
    while d * d <= n:
        if n % d == 0:
            small.append(d)
            if d * d != n:
                large.append(n // d)
        d += 1
    return small + large[::-1]


def _net_stroke_rule(periodic: bool, num: int, den: int) -> str:
    """The rule a net stroke ``num / den`` counts per period breaks, or "" (FORMAT.md, loader
    rule -34): a reduced fraction with 1 <= den <= 2^32 - 1, less than 2^31 counts per period,
    and 0/1 unless the table is periodic."""
    if not 1 <= den <= MAX_NET_DENOMINATOR or not -(2**63) <= num < 2**63:
        return "an int64 over a denominator in 1..2^32-1"
    if math.gcd(num, den) != 1:
        return "a reduced fraction (gcd(|num|, den) = 1; 0/1 for none)"
    if abs(num) >= den * 2**31:
        return "less than 2^31 counts per period"
    if num and not periodic:
        return "0/1 for a table that is not periodic"
    return ""


def net_stroke_term(turns, num: int, den: int) -> np.ndarray:
    """``floor((turns * num + floor(den/2)) / den)`` modulo 2^64, for int64 ``turns``, in int64
    and uint64 words only (FORMAT.md step 7; the C runtime does the same): with
    ``num = A den + B`` (0 <= B < den) and ``turns = kh den + kl`` (0 <= kl < den), it is
    ``turns A + kh B + floor((kl B + floor(den/2)) / den)``, whose last product stays below 2^64."""
    turns = np.asarray(turns, dtype=np.int64)
    whole, rest = divmod(num, den)
    with np.errstate(over="ignore"):
        term = turns * np.int64(whole)
        if rest:
            high = np.floor_divide(turns, den)
            low = (turns - high * den).astype(np.uint64)
            term += high * np.int64(rest)
            term += ((low * np.uint64(rest) + np.uint64(den // 2)) // np.uint64(den)).astype(np.int64)
    return term


_INT64_RANGE = "in -2^63..2^63-1 (int64 counts)"


def _as_counts(master_counts) -> np.ndarray:
    """``master_counts`` as int64, or the one-line InputError naming the first value refused."""
    if isinstance(master_counts, (bool, np.bool_)):
        raise fail("master_counts", master_counts, "an integer (int64 counts)")
    try:
        array = np.asarray(master_counts)
    except (ValueError, TypeError):  # ragged nesting
        raise fail("master_counts", master_counts, "integers (int64 counts)") from None
    whole = "an integer (int64 counts)" if array.ndim == 0 else "integers (int64 counts)"
    if array.dtype == object:  # Python ints beyond int64, or a mix of types
        for value in array.flat:
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
                raise fail("master_counts", value, whole)
            if not -(2**63) <= value < 2**63:
                raise fail("master_counts", value, _INT64_RANGE)
        return array.astype(np.int64)
    if array.dtype.kind not in "iu":
        first = array.flat[0].item() if array.size else master_counts
        raise fail("master_counts", first, f"{whole}, not {array.dtype}")
    if array.dtype == np.uint64 and array.size and array.max() > np.iinfo(np.int64).max:
        raise fail("master_counts", int(array.max()), _INT64_RANGE)
    return array.astype(np.int64, copy=False)


def _unwrap(values, original):
    return int(values[0]) if np.ndim(original) == 0 else values
