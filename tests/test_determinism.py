"""Golden files are compared byte for byte on whatever machine runs the tests, so what generates
them must give the same bits on every CPU: no LAPACK/BLAS (numpy.linalg, the @ operator), whose
kernels OpenBLAS picks per CPU at run time. ecam.linear solves in a fixed order instead."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from ecam.export.kollmorgen import spline_slopes
from ecam.laws import polynomial_from_boundary
from ecam.linear import inverse_exact, matmul, solve_exact, solve_sparse

CORE = Path(__file__).resolve().parents[1] / "ecam"


def _blas_uses(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            found.append(f"{path.name}:{node.lineno} @")
        if isinstance(node, ast.Attribute) and node.attr in ("linalg", "dot", "matmul", "einsum"):
            found.append(f"{path.name}:{node.lineno} .{node.attr}")
    return found


def test_the_core_calls_no_blas_or_lapack():
    files = [p for p in CORE.rglob("*.py") if "app" not in p.relative_to(CORE).parts]
    assert len(files) > 20
    uses = [u for p in files for u in _blas_uses(p)]
    assert not uses, uses


def test_exact_solutions_are_correctly_rounded():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(7, 7))
    x = rng.normal(size=7)
    b = [float(v) for v in matmul(a, x)]
    assert np.allclose(solve_exact(a.tolist(), b), x, rtol=1e-12, atol=1e-12)
    assert np.allclose(matmul(inverse_exact(a.tolist()), a), np.eye(7), atol=1e-12)
    # a 7th-order rise with rest at both ends is 35u^4 - 84u^5 + 70u^6 - 20u^7, exactly
    law = polynomial_from_boundary((0, 0, 0), (0, 0, 0))
    assert law.pieces[0].poly == (0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0)


def test_sparse_solve_matches_a_dense_one_on_a_bordered_band():
    rng = np.random.default_rng(6)
    n = 40
    dense = np.zeros((n, n))
    for i in range(n):
        for j in (i - 1, i, i + 1):
            if 0 <= j < n:
                dense[i, j] = rng.normal() + (4.0 if i == j else 0.0)
    dense[0, n - 1], dense[n - 1, 0], dense[n - 1, 1] = 1.5, -2.0, 0.7
    rhs = rng.normal(size=n)
    rows = [{j: dense[i, j] for j in range(n) if dense[i, j] != 0.0} for i in range(n)]
    assert np.allclose(matmul(dense, solve_sparse(rows, rhs)), rhs, atol=1e-12)


def test_periodic_spline_slopes_satisfy_their_conditions():
    x = np.array([0.0, 1.0, 2.5, 3.0, 4.5, 6.0])
    y = np.sin(x * 2 * np.pi / 6.0)
    m = spline_slopes(x, y, "periodic")
    h, d = np.diff(x), np.diff(y) / np.diff(x)
    assert abs(m[0] - m[-1]) < 1e-12
    curv_out = (6 * d[0] - 4 * m[0] - 2 * m[1]) / h[0]
    curv_in = (-6 * d[-1] + 2 * m[-2] + 4 * m[-1]) / h[-1]
    assert abs(curv_out - curv_in) < 1e-12
