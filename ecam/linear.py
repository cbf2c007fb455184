"""Small linear systems solved the same way on every machine.

numpy.linalg and the ``@`` operator call LAPACK/BLAS, whose kernels differ between CPUs (OpenBLAS
picks one at run time): the last bits of a solution, and with them the committed golden files,
would depend on the machine that generated them. Everything here is plain IEEE arithmetic in a
fixed order, or exact rational arithmetic rounded once, so the same input gives the same bits.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Sequence

import numpy as np


def solve_exact(rows: Sequence[Sequence[float]], rhs: Sequence[float]) -> list[float]:
    """x with rows @ x = rhs, computed exactly in rationals and rounded once to float.

    For small systems (polynomial boundary conditions, Hermite bases): every float is an exact
    rational, so the result is the correctly rounded solution. Raises ZeroDivisionError when the
    matrix is singular.
    """
    n = len(rows)
    a = [[Fraction(v) for v in row] + [Fraction(b)] for row, b in zip(rows, rhs)]
    for col in range(n):
        pivot = next((r for r in range(col, n) if a[r][col] != 0), None)
        if pivot is None:
            raise ZeroDivisionError("singular matrix")
        a[col], a[pivot] = a[pivot], a[col]
        head = a[col]
        for r in range(n):
            if r != col and a[r][col] != 0:
                factor = a[r][col] / head[col]
                a[r] = [x - factor * y for x, y in zip(a[r], head)]
    return [float(a[r][n] / a[r][r]) for r in range(n)]


def inverse_exact(matrix: Sequence[Sequence[float]]) -> np.ndarray:
    """The inverse of a small matrix, exact in rationals, rounded once per entry."""
    n = len(matrix)
    columns = [solve_exact(matrix, [1.0 if i == j else 0.0 for i in range(n)]) for j in range(n)]
    return np.array(columns, dtype=float).T


def solve_sparse(rows: Sequence[dict], rhs: Sequence[float]) -> np.ndarray:
    """x with A x = rhs for a sparse A given as one {column: value} dict per row: Gaussian
    elimination with partial pivoting in float64, in a fixed order.

    Meant for banded systems with a few extra entries (cubic splines with any end condition):
    fill-in stays within the band and the bordering rows, so the cost is linear in the size.
    """
    n = len(rows)
    a = [dict(row) for row in rows]
    b = [float(v) for v in rhs]
    by_column: list[set] = [set() for _ in range(n)]  # rows not yet eliminated with an entry there
    for r, row in enumerate(a):
        for c in row:
            by_column[c].add(r)
    order = []
    for col in range(n):
        candidates = sorted(by_column[col])
        if not candidates:
            raise ZeroDivisionError("singular matrix")
        pivot = max(candidates, key=lambda r: (abs(a[r][col]), -r))
        for c in a[pivot]:
            by_column[c].discard(pivot)
        head, head_b, value = a[pivot], b[pivot], a[pivot][col]
        for r in candidates:
            if r == pivot:
                continue
            factor = a[r][col] / value
            row = a[r]
            for c, v in head.items():
                if c == col:
                    continue
                if c not in row:
                    by_column[c].add(r)
                row[c] = row.get(c, 0.0) - factor * v
            del row[col]
            by_column[col].discard(r)
            b[r] -= factor * head_b
        order.append(pivot)
    x = np.zeros(n)
    for col in range(n - 1, -1, -1):
        r = order[col]
        total = b[r]
        for c, v in a[r].items():
            if c != col:
                total -= v * x[c]
        x[col] = total / a[r][col]
    return x


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b with the products summed in index order (no BLAS): a (..., k), b (k,) or (k, m)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    column = b.ndim == 1
    if column:
        b = b[:, None]
    out = a[..., 0, None] * b[0]
    for k in range(1, b.shape[0]):
        out = out + a[..., k, None] * b[k]
    return out[..., 0] if column else out
