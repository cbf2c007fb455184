"""Normalized motion laws s(u): u in [0, 1], s(0) = 0, s(1) = 1.

Every law is stored as pieces over sub-intervals of [0, 1]; on a piece starting at ``u0`` the
law is a polynomial in the local variable ``t = u - u0`` plus a sum of sinusoids
``a * sin(w * t + phase)``. That one representation covers every classical cam law, and it
gives exact derivatives of any order: the error certificate of the table compiler needs the 4th
and 6th derivatives, not just the jerk.

Laws whose acceleration is given piecewise (modified trapezoid, modified sine, modified constant
velocity) are integrated here from that acceleration, so their coefficients are derived rather
than typed in. Characteristic values ``cv``, ``ca``, ``cj`` (peaks of |s'|, |s''|, |s'''|) are
measured from the law itself; ``math.inf`` marks an unbounded value (an impulse inside the law,
or a jump against the rest it starts or ends in).

The dwell (:data:`DWELL`, ``law("dwell")``) is the one law that does not rise: s(u) = 0, for
segments of zero stroke. It is accepted wherever a law is, but it is not in :data:`LAWS`, the
registry of rise laws.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__

__all__ = ["DWELL", "Law", "LAWS", "LAW_NAMES", "LawTable", "law", "polynomial_from_boundary"]

_PI = math.pi
# Up to this many inner breaks a law's piece is found by one pass over the points per break;
# beyond (a spline segment's knots), by bisection.
_FEW_BREAKS = 16
SIDES = ("right", "left")


@dataclass(frozen=True)
class Piece:
    """One smooth piece: ``sum(poly[i] * t**i) + sum(a * sin(w * t + phase))``, t = u - start."""

    start: float
    end: float
    poly: tuple[float, ...] = ()
    waves: tuple[tuple[float, float, float], ...] = ()

    def evaluate(self, t: np.ndarray, order: int) -> np.ndarray:
        out = np.zeros_like(t)
        coeffs = np.asarray(self.poly, dtype=float)
        for _ in range(order):
            coeffs = coeffs[1:] * np.arange(1, len(coeffs))
        for c in coeffs[::-1]:  # Horner
            out = out * t + c
        for amplitude, omega, phase in self.waves:
            out = out + amplitude * omega**order * np.sin(omega * t + phase + order * _PI / 2)
        return out

    def integrate(self, initial: float) -> "Piece":
        """Antiderivative with value ``initial`` at the piece start."""
        poly = [0.0] + [c / (i + 1) for i, c in enumerate(self.poly)]
        waves = tuple((a / w, w, p - _PI / 2) for a, w, p in self.waves)
        start_value = sum(a * math.sin(p) for a, _, p in waves)
        poly[0] = initial - start_value
        return Piece(self.start, self.end, tuple(poly), waves)

    def scaled(self, factor: float) -> "Piece":
        return Piece(
            self.start,
            self.end,
            tuple(c * factor for c in self.poly),
            tuple((a * factor, w, p) for a, w, p in self.waves),
        )

    def value_at_end(self, order: int = 0) -> float:
        return float(self.evaluate(np.array([self.end - self.start]), order)[0])


@dataclass(frozen=True)
class Law:
    """A normalized rise law, callable as ``law(u, order=0)``: s(0) = 0, s(1) = 1 (the dwell,
    s = 0, is the one exception).

    Parameters
    ----------
    name : str
        Lowercase words joined by underscores.
    pieces : tuple of Piece
        Contiguous smooth pieces covering [0, 1].
    rest_start, rest_end : bool
        Whether the law is meant to start (end) at rest, next to a dwell. A derivative that is
        not zero at such an end is a jump against the dwell, which makes the next characteristic
        value infinite, as the published tables count it.
    description : str
        One line for tables and plots.
    """

    name: str
    pieces: tuple[Piece, ...]
    rest_start: bool = True
    rest_end: bool = True
    description: str = ""
    _breaks: np.ndarray = field(init=False, repr=False, compare=False)
    # Characteristic values live on the law itself: a cache keyed by id() would hand a freed
    # law's values to the next law allocated at the same address.
    _characteristics: dict = field(init=False, repr=False, compare=False, default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "_breaks", np.array([p.start for p in self.pieces[1:]]))

    def __call__(self, u, order: int = 0, side: str = "right"):
        """Evaluate the law or its derivative of ``order`` (0 position, 1 velocity, ...).

        Parameters
        ----------
        u : array_like
            Normalized master position(s) in [0, 1].
        order : int
            Derivative order, 0 or more (d^order s / du^order).
        side : {'right', 'left'}
            Which one-sided limit to take at an inner break of the law.

        Raises
        ------
        InputError
            ``order`` is not an integer >= 0, or ``side`` is neither 'right' nor 'left'.
        """
        order = validate.integer("order", int(order) if isinstance(order, np.integer) else order, minimum=0)
        validate.choice("side", side, SIDES)
        scalar = np.ndim(u) == 0
        u = np.asarray(u, dtype=float)
        index = np.searchsorted(self._breaks, u, side="right" if side == "right" else "left")
        out = np.empty_like(u)
        for i, piece in enumerate(self.pieces):
            mask = index == i
            if mask.any():
                out[mask] = piece.evaluate(u[mask] - piece.start, order)
        return float(out) if scalar else out

    # characteristic values -------------------------------------------------------------
    @property
    def cv(self) -> float:
        """Peak |s'| over the rise."""
        return self.characteristic(1)

    @property
    def ca(self) -> float:
        """Peak |s''|; inf where the velocity jumps."""
        return self.characteristic(2)

    @property
    def cj(self) -> float:
        """Peak |s'''|; inf where the acceleration jumps."""
        return self.characteristic(3)

    def characteristic(self, order: int) -> float:
        """Peak of |d^order s/du^order|, or inf if a lower derivative jumps (an impulse)."""
        return _characteristic(self, order)

    def jumps(self, order: int) -> list[tuple[float, float]]:
        """Inner breaks where the derivative of ``order`` jumps: list of (u, right - left)."""
        out = []
        for u0 in self._breaks:
            left = self(u0, order, side="left")
            right = self(u0, order, side="right")
            scale = max(1.0, abs(left), abs(right))
            if abs(right - left) > 1e-9 * scale:
                out.append((float(u0), right - left))
        return out

    @property
    def breaks(self) -> tuple[float, ...]:
        """Inner break points of the law (where a piece ends)."""
        return tuple(float(b) for b in self._breaks)


class LawTable:
    """Many laws evaluated in one pass: ``table(which, u, order, left)`` is ``laws[which[k]](u[k],
    order, side)`` for every k, with the same bits.

    A cam of thousands of segments evaluates each point with its own segment's law; calling each
    law on its own points costs a pass over all the points per law (quadratic in the segments).
    Here the pieces of every law are stacked into arrays (breaks, polynomial coefficients padded
    with zeros above the highest degree, sinusoids), and a point picks its piece's row: the same
    Horner steps and sinusoids as :meth:`Piece.evaluate`, element by element, so the result is
    the law's own to the last bit (a leading zero coefficient adds an exact 0 in Horner's rule).

    Parameters
    ----------
    laws : sequence of Law
        The laws, indexed by ``which``.
    """

    def __init__(self, laws) -> None:
        self.laws = tuple(laws)
        pieces = [piece for law_ in self.laws for piece in law_.pieces]
        counts = np.array([len(law_.pieces) for law_ in self.laws], dtype=np.int64)
        self.first_piece = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        # Laws of many breaks (a spline's knots) find their piece by bisection; the others by a
        # pass per break column, over the columns they use only.
        self._many = [(i, np.array(law_.breaks)) for i, law_ in enumerate(self.laws)
                      if len(law_.breaks) > _FEW_BREAKS]
        narrow = max((len(law_.breaks) for law_ in self.laws if len(law_.breaks) <= _FEW_BREAKS), default=0)
        # Inner breaks, one row per law, NaN past a law's own (NaN compares false: no piece step);
        # the columns the laws of few breaks use (a spline's knots would make it laws x knots).
        self.breaks = np.full((len(self.laws), narrow), np.nan)
        for i, law_ in enumerate(self.laws):
            if len(law_.breaks) <= _FEW_BREAKS:
                self.breaks[i, : len(law_.breaks)] = law_.breaks
        self._break_columns = [self.breaks[:, k].copy() for k in range(narrow)]
        # Every law's breaks in one array: law i's are break_values[break_first[i]:][:break_count[i]].
        self.break_count = counts - 1
        self.break_first = np.concatenate([[0], np.cumsum(self.break_count)[:-1]]).astype(np.int64)
        self.break_values = np.array([b for law_ in self.laws for b in law_.breaks], dtype=float)
        self.piece_start = np.array([piece.start for piece in pieces])
        self.piece_end = np.array([piece.end for piece in pieces])
        width = max(1, max(len(piece.poly) for piece in pieces))
        self._poly = np.zeros((len(pieces), width))
        for i, piece in enumerate(pieces):
            self._poly[i, : len(piece.poly)] = piece.poly
        self._coefficients = {0: self._poly}
        self._coefficient_columns: dict[int, list[np.ndarray]] = {}
        waves = max(len(piece.waves) for piece in pieces)
        self.wave_count = np.array([len(piece.waves) for piece in pieces], dtype=np.int64)
        self._waves = [piece.waves for piece in pieces]
        self._omega = np.zeros((len(pieces), waves))
        self._phase = np.zeros((len(pieces), waves))
        for i, piece in enumerate(pieces):
            for k, (_, omega, phase) in enumerate(piece.waves):
                self._omega[i, k], self._phase[i, k] = omega, phase
        self._wave_factors: dict[int, np.ndarray] = {}
        self._ranges: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def coefficients(self, order: int) -> np.ndarray:
        """Polynomial coefficients of derivative ``order``, one row per piece (lowest first)."""
        if order not in self._coefficients:
            below = self.coefficients(order - 1)
            self._coefficients[order] = below[:, 1:] * np.arange(1, below.shape[1])
        return self._coefficients[order]

    def _columns(self, order: int) -> list[np.ndarray]:
        """The coefficients of derivative ``order`` column by column (one array per power)."""
        if order not in self._coefficient_columns:
            coefficients = self.coefficients(order)
            self._coefficient_columns[order] = [coefficients[:, j].copy() for j in range(coefficients.shape[1])]
        return self._coefficient_columns[order]

    def wave_factors(self, order: int) -> np.ndarray:
        """``amplitude * omega**order`` of every sinusoid, in Python floats as Piece.evaluate has it."""
        if order not in self._wave_factors:
            factors = np.zeros(self._omega.shape)
            for i, waves in enumerate(self._waves):
                for k, (amplitude, omega, _) in enumerate(waves):
                    factors[i, k] = amplitude * omega**order
            self._wave_factors[order] = factors
        return self._wave_factors[order]

    def __call__(self, which: np.ndarray, u: np.ndarray, order: int, left=False, snap: bool = False) -> np.ndarray:
        """d^order s / du^order of law ``which[k]`` at ``u[k]``.

        ``left`` (a bool, or one per point) takes the left limit at an inner break, as
        ``side="left"`` does. ``snap`` first moves a ``u`` that misses a break of its law by less
        than 1e-12 onto it, as :meth:`ecam.profile.Segment.evaluate` does for a ``u``
        recomputed from a master position.
        """
        breaks = [column[which] for column in self._break_columns]
        if snap:
            for b in breaks:
                u = np.where(np.abs(u - b) < 1e-12, b, u)
        piece = self.first_piece[which]
        for b in breaks:
            piece = piece + np.where(left, b < u, b <= u)  # np.searchsorted, side left/right
        if self._many:
            u, piece = self._bisect(which, u, left, snap, piece)
        return self.pieces_at(piece, u - self.piece_start[piece], order)

    def _bisect(self, which, u, left, snap, piece):
        """The piece of every point of a law with many breaks, by bisection (as the passes above
        count it: side left/right, and ``snap`` onto a break within 1e-12)."""
        u, piece = np.array(u, dtype=float), np.array(piece)
        for index, breaks in self._many:
            mask = which == index
            if not mask.any():
                continue
            local = u[mask]
            if snap:
                near = np.clip(np.searchsorted(breaks, local), 1, breaks.size) - 1
                for candidate in (breaks[near], breaks[np.minimum(near + 1, breaks.size - 1)]):
                    local = np.where(np.abs(local - candidate) < 1e-12, candidate, local)
            side_left = left if np.ndim(left) == 0 else np.asarray(left)[mask]
            count = np.where(side_left, np.searchsorted(breaks, local, side="left"),
                             np.searchsorted(breaks, local, side="right"))
            u[mask], piece[mask] = local, self.first_piece[index] + count
        return u, piece

    def pieces_at(self, piece: np.ndarray, t: np.ndarray, order: int) -> np.ndarray:
        """Piece ``piece[k]`` (a row of the stacked pieces) at local ``t[k]``: Piece.evaluate."""
        out = np.zeros_like(t)
        for column in reversed(self._columns(order)):  # Horner, from the highest degree
            out = out * t + column[piece]
        if self._omega.shape[1]:
            factors = self.wave_factors(order)
            for k in range(self._omega.shape[1]):
                has = self.wave_count[piece] > k
                if has.any():
                    p, local = piece[has], t[has]
                    out[has] = out[has] + factors[p, k] * np.sin(self._omega[p, k] * local + self._phase[p, k]
                                                                 + order * _PI / 2)
        return out

    def piece_ranges(self, order: int, samples: int = 1025) -> tuple[np.ndarray, np.ndarray]:
        """Smallest and largest d^order s/du^order of each piece, sampled at ``samples`` evenly
        spaced points of the piece, its own polynomial at both ends (one-sided limits)."""
        if order not in self._ranges:
            low, high = np.empty(self.piece_start.size), np.empty(self.piece_start.size)
            grid = np.linspace(0.0, 1.0, samples)
            rows = max(1, 2**20 // samples)  # a bounded working set however many pieces
            for first in range(0, self.piece_start.size, rows):
                piece = np.arange(first, min(first + rows, self.piece_start.size))
                width = (self.piece_end - self.piece_start)[piece]
                t = width[:, None] * grid[None, :]
                values = self.pieces_at(np.repeat(piece, samples), t.ravel(), order).reshape(t.shape)
                low[piece], high[piece] = values.min(axis=1), values.max(axis=1)
            self._ranges[order] = (low, high)
        return self._ranges[order]


def _characteristic(law: Law, order: int) -> float:
    cache = law._characteristics
    if order in cache:
        return cache[order]
    value = _peak(law, order)
    for k in range(1, order):
        if law.jumps(k):
            value = math.inf
        for at_rest, u in ((law.rest_start, 0.0), (law.rest_end, 1.0)):
            if at_rest and abs(law(u, k)) > 1e-9 * max(1.0, _peak(law, k)):
                value = math.inf
    cache[order] = value
    return value


def _peak(law: Law, order: int) -> float:
    """Peak of |s^(order)| found on a dense grid and polished by Newton on s^(order+1) = 0."""
    best = 0.0
    for piece in law.pieces:
        width = piece.end - piece.start
        t = np.linspace(0.0, width, 4097)
        values = np.abs(piece.evaluate(t, order))
        best = max(best, float(values[0]), float(values[-1]))
        i = int(np.argmax(values))
        ti = t[i]
        for _ in range(30):  # Newton on the derivative; stays inside the piece
            d1 = float(piece.evaluate(np.array([ti]), order + 1)[0])
            d2 = float(piece.evaluate(np.array([ti]), order + 2)[0])
            if d2 == 0.0:
                break
            step = d1 / d2
            ti = min(max(ti - step, 0.0), width)
            if abs(step) < 1e-15:
                break
        best = max(best, float(values[i]), abs(float(piece.evaluate(np.array([ti]), order)[0])))
    return best


# --- construction helpers -------------------------------------------------------------------


def _from_acceleration(name, pieces, description, initial_velocity=0.0, rest=(True, True)):
    """Integrate a piecewise acceleration twice from rest and scale it so that s(1) = 1."""
    velocity, position = [], []
    v0, s0 = initial_velocity, 0.0
    for acc in pieces:
        v = acc.integrate(v0)
        s = v.integrate(s0)
        velocity.append(v)
        position.append(s)
        v0, s0 = v.value_at_end(), s.value_at_end()
    scale = 1.0 / s0
    return Law(name, tuple(p.scaled(scale) for p in position), *rest, description)


def _single(name, poly=(), waves=(), description="", rest=(True, True)):
    return Law(name, (Piece(0.0, 1.0, tuple(poly), tuple(waves)),), *rest, description)


def _acc(start, end, poly=(), waves=()):
    return Piece(start, end, tuple(poly), tuple(waves))


def _build_laws() -> dict[str, Law]:
    laws = {}

    def add(law_):
        laws[law_.name] = law_

    add(_single("constant_velocity", (0.0, 1.0), description="s = u"))
    add(
        Law(
            "constant_acceleration",
            (Piece(0.0, 0.5, (0.0, 0.0, 2.0)), Piece(0.5, 1.0, (0.5, 2.0, -2.0))),
            description="parabolic: s = 2u^2, then mirrored",
        )
    )
    add(_single("harmonic", (0.5,), ((-0.5, _PI, _PI / 2),), "simple harmonic: (1 - cos(pi u))/2"))
    add(_single("cycloidal", (0.0, 1.0), ((-1 / (2 * _PI), 2 * _PI, 0.0),), "u - sin(2 pi u)/(2 pi)"))
    add(_single("cubic", (0.0, 0.0, 3.0, -2.0), description="3u^2 - 2u^3"))
    add(_single("poly345", (0.0, 0.0, 0.0, 10.0, -15.0, 6.0), description="10u^3 - 15u^4 + 6u^5"))
    add(
        _single(
            "poly4567",
            (0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0),
            description="35u^4 - 84u^5 + 70u^6 - 20u^7",
        )
    )
    # Modified trapezoid: sine ramps of the acceleration over 1/8, constant between.
    w = 4 * _PI
    add(
        _from_acceleration(
            "modified_trapezoid",
            [
                _acc(0.0, 0.125, waves=((1.0, w, 0.0),)),
                _acc(0.125, 0.375, poly=(1.0,)),
                _acc(0.375, 0.625, waves=((1.0, w, _PI / 2),)),
                _acc(0.625, 0.875, poly=(-1.0,)),
                _acc(0.875, 1.0, waves=((-1.0, w, _PI / 2),)),
            ],
            "sine ramps over 1/8, constant acceleration between",
        )
    )
    # Modified sine: fast quarter sine over 1/8, slow sine (period 3/2) over 3/4, fast again.
    add(
        _from_acceleration(
            "modified_sine",
            [
                _acc(0.0, 0.125, waves=((1.0, w, 0.0),)),
                _acc(0.125, 0.875, waves=((1.0, 4 * _PI / 3, _PI / 2),)),
                _acc(0.875, 1.0, waves=((-1.0, w, _PI / 2),)),
            ],
            "quarter sines over 1/8 at the ends, slow sine between",
        )
    )
    # Modified constant velocity: cycloidal (half-sine acceleration) ramps over the first and
    # last quarter, constant velocity between.
    add(
        _from_acceleration(
            "modified_constant_velocity",
            [
                _acc(0.0, 0.25, waves=((1.0, w, 0.0),)),
                _acc(0.25, 0.75),
                _acc(0.75, 1.0, waves=((-1.0, w, 0.0),)),
            ],
            "cycloidal ramps over the first and last quarter, constant velocity between",
        )
    )
    # Half curves of combination cams (Cam Design Handbook, combination curves):
    # C1 starts at rest and ends at peak velocity, C2 the reverse; H1/H2 likewise for harmonics.
    add(
        _single(
            "half_cycloid_start",
            (0.0, 1.0),
            ((-1 / _PI, _PI, 0.0),),
            "C1: first half of a cycloid, rest to peak velocity",
            rest=(True, False),
        )
    )
    add(
        _single(
            "half_cycloid_end",
            (0.0, 1.0),
            ((1 / _PI, _PI, 0.0),),
            "C2: second half of a cycloid, peak velocity to rest",
            rest=(False, True),
        )
    )
    add(
        _single(
            "half_harmonic_start",
            (1.0,),
            ((-1.0, _PI / 2, _PI / 2),),
            "H1: first half of a harmonic, rest to peak velocity: 1 - cos(pi u/2)",
            rest=(True, False),
        )
    )
    add(
        _single(
            "half_harmonic_end",
            (),
            ((1.0, _PI / 2, 0.0),),
            "H2: second half of a harmonic, peak velocity to rest: sin(pi u/2)",
            rest=(False, True),
        )
    )
    return laws


LAWS: dict[str, Law] = _build_laws()

DWELL = Law("dwell", (Piece(0.0, 1.0),), description="dwell: the slave holds, s = 0 (zero stroke)")

# Every name law() accepts: the rise laws and the dwell.
LAW_NAMES: tuple[str, ...] = tuple(sorted([*LAWS, DWELL.name]))


def law(name) -> Law:
    """The law called ``name``: one of :data:`LAWS` or ``"dwell"`` (:data:`DWELL`).

    Parameters
    ----------
    name : str or Law
        A law name (see :data:`LAW_NAMES`); a :class:`Law` is returned as it is.

    Raises
    ------
    InputError
        ``law: <name> should be one of ...`` for an unknown name.
    """
    if isinstance(name, Law):
        return name
    if name == DWELL.name:
        return DWELL
    return LAWS[validate.choice("law", name, LAW_NAMES)]


def polynomial_from_boundary(start, end, name: str = "polynomial") -> Law:
    """Polynomial rise law solved from boundary conditions at both ends (VDI 2143).

    Parameters
    ----------
    start, end : sequence of float
        Normalized derivatives at u = 0 and u = 1, each ``(s', s'')`` for a 5th-order polynomial
        or ``(s', s'', s''')`` for a 7th-order one. Position is s(0) = 0, s(1) = 1.

    Returns
    -------
    Law
        The unique polynomial of degree 2k+1 (k = len(start)) meeting the conditions.

    Raises
    ------
    InputError
        ``start`` does not hold 2 or 3 values, ``end`` not as many, or a value is not a finite
        number.
    """
    start, end = _conditions("start", start), _conditions("end", end)
    if len(start) not in (2, 3):
        raise validate.fail("start", start, "2 values (5th order) or 3 values (7th order)")
    if len(end) != len(start):
        raise validate.fail("end", end, f"{len(start)} values, as many as start")
    k = len(start)
    degree = 2 * k + 1
    coeffs = _boundary_coefficients(start, end)  # the same bits on every machine
    rest_start = all(v == 0.0 for v in start)
    rest_end = all(v == 0.0 for v in end)
    return Law(
        name,
        (Piece(0.0, 1.0, tuple(float(c) for c in coeffs)),),
        rest_start,
        rest_end,
        f"{degree}th-order polynomial from boundary conditions",
    )


def _boundary_coefficients(start: tuple[float, ...], end: tuple[float, ...]) -> list[float]:
    """Coefficients c_0..c_(2k+1) (lowest first) of the polynomial with s(0) = 0, s(1) = 1 and
    the derivatives ``start`` at 0 and ``end`` at 1, exact in rationals and rounded once.

    The conditions at 0 give c_0..c_k directly (c_o = s^(o)(0) / o!); those at 1 leave a
    (k+1) x (k+1) system for the rest whose matrix is the same for every segment, so its exact
    inverse is computed once: a cam of many polynomial segments costs a few rational products
    each, not an elimination. The solution is the same rational number as any exact solve
    (:func:`ecam.linear.solve_exact`), hence the same float.
    """
    k = len(start)
    low = [Fraction(0)] + [Fraction(value) / math.factorial(o) for o, value in enumerate(start, start=1)]
    at_end = [Fraction(1)] + [Fraction(value) for value in end]
    residual = [at_end[o] - sum(_falling(i, o) * low[i] for i in range(o, k + 1)) for o in range(k + 1)]
    inverse = _end_inverse(k)
    high = [sum(inverse[j][o] * residual[o] for o in range(k + 1)) for j in range(k + 1)]
    return [float(c) for c in low + high]


def _falling(i: int, order: int) -> int:
    """d^order/du^order of u^i at u = 1: i! / (i - order)!."""
    return math.factorial(i) // math.factorial(i - order)


@functools.cache
def _end_inverse(k: int) -> tuple[tuple[Fraction, ...], ...]:
    """Exact inverse of the matrix taking c_(k+1)..c_(2k+1) to s(1), s'(1), .., s^(k)(1)
    (Gauss-Jordan in rationals; the matrix is regular for every k)."""
    size = k + 1
    rows = [[Fraction(_falling(i, o)) for i in range(k + 1, 2 * k + 2)] + [Fraction(int(o == j)) for j in range(size)]
            for o in range(size)]
    for col in range(size):
        pivot = next(r for r in range(col, size) if rows[r][col] != 0)
        rows[col], rows[pivot] = rows[pivot], rows[col]
        head = [value / rows[col][col] for value in rows[col]]
        rows[col] = head
        for r in range(size):
            if r != col and rows[r][col] != 0:
                factor = rows[r][col]
                rows[r] = [x - factor * y for x, y in zip(rows[r], head)]
    return tuple(tuple(row[size:]) for row in rows)


def _conditions(field: str, values) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
        raise validate.fail(field, values, "a sequence of 2 or 3 numbers")
    return tuple(validate.number(f"{field}[{i}]", v.item() if isinstance(v, np.generic) else v)
                 for i, v in enumerate(values))
