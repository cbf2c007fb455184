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

import math
from dataclasses import dataclass, field

import numpy as np

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .linear import solve_exact

__all__ = ["DWELL", "Law", "LAWS", "LAW_NAMES", "law", "polynomial_from_boundary"]

_PI = math.pi
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
    rows, rhs = [], []
    for u, values in ((0.0, (0.0,) + start), (1.0, (1.0,) + end)):
        for order, value in enumerate(values):
            row = [
                math.factorial(i) / math.factorial(i - order) * u ** (i - order) if i >= order else 0.0
                for i in range(degree + 1)
            ]
            rows.append(row)
            rhs.append(value)
    coeffs = solve_exact(rows, rhs)  # the same bits on every machine (ecam.linear)
    rest_start = all(v == 0.0 for v in start)
    rest_end = all(v == 0.0 for v in end)
    return Law(
        name,
        (Piece(0.0, 1.0, tuple(float(c) for c in coeffs)),),
        rest_start,
        rest_end,
        f"{degree}th-order polynomial from boundary conditions",
    )


def _conditions(field: str, values) -> tuple[float, ...]:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
        raise validate.fail(field, values, "a sequence of 2 or 3 numbers")
    return tuple(validate.number(f"{field}[{i}]", v.item() if isinstance(v, np.generic) else v)
                 for i, v in enumerate(values))
