"""Exact discretization of linear models, and their steps as straight-line float arithmetic.

Each model is x' = A x + B u with the inputs u held constant over a step of ``dt``. The step is
exact: ``[[Phi, Gamma], [0, 1]] = expm([[A, B], [0, 0]] dt)``, so a coupling of 1e9 N m/rad runs
at the same step as one of 10 N m/rad (an explicit integrator would need a step below 2/omega,
i.e. microseconds, to stay stable).

The matrix exponential is written here (numpy only): balancing by powers of two, then scaling and
squaring with the degree-13 Pade approximant of Higham (2005).

A step x -> Phi x + Gamma u of a 2..5-state model costs more in numpy call overhead than in
arithmetic, and the rig runs it several times per bus cycle: :func:`linear_step` compiles it
into one Python function of plain float products and sums (same terms, fixed order, so the
result is the same on every run).
"""

from __future__ import annotations

import math

import numpy as np

from ecam.errors import InputError

# Higham (2005), "The scaling and squaring method for the matrix exponential revisited",
# Table 2.3 / eq. (2.3): coefficients b_0..b_13 of the [13/13] Pade approximant, and the
# 1-norm below which it is accurate to double precision without scaling.
_PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
           1187353796428800.0, 129060195264000.0, 10559470521600.0, 670442572800.0,
           33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0)
_THETA13 = 5.371920351148152


def _balance(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (D^-1 A D, d) with d = diag(D) powers of two that even out row and column norms.

    Physical states differ by many orders of magnitude (an angle and a speed of a 1e9 N m/rad
    coupling); balancing shrinks the norm, so expm needs fewer squarings and loses less
    precision. Powers of two make the similarity transform itself exact.
    """
    b = a.copy()
    d = np.ones(b.shape[0])
    for _ in range(100):
        changed = False
        for i in range(b.shape[0]):
            col = np.abs(b[:, i]).sum() - abs(b[i, i])
            row = np.abs(b[i, :]).sum() - abs(b[i, i])
            if col == 0.0 or row == 0.0:
                continue  # an input column or a pure integrator row: nothing to even out
            f = 2.0 ** round(0.5 * math.log2(row / col))
            if col * f + row / f < 0.95 * (col + row):
                b[:, i] *= f
                b[i, :] /= f
                d[i] *= f
                changed = True
        if not changed:
            break
    return b, d


def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential of a real square matrix.

    Parameters
    ----------
    a : ndarray, shape (n, n)
        Finite real matrix.

    Returns
    -------
    ndarray, shape (n, n)
        exp(a).

    Raises
    ------
    InputError
        If ``a`` is not square or not finite.

    Notes
    -----
    Balancing (diagonal similarity by powers of two), then scaling by 2^-s so that
    ||a||_1 <= 5.37, the [13/13] Pade approximant, and s squarings (Higham 2005). Accurate
    to a few ulps times the condition of the problem; validated against scipy in the tests.
    """
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise InputError(f"matrix shape {a.shape} should be square")
    if not np.all(np.isfinite(a)):
        raise InputError("matrix entries should be finite")
    n = a.shape[0]
    b, d = _balance(a)
    norm = np.abs(b).sum(axis=0).max()
    s = max(0, math.ceil(math.log2(norm / _THETA13))) if norm > 0.0 else 0
    b = b / 2.0**s
    c = _PADE13
    ident = np.eye(n)
    b2 = b @ b
    b4 = b2 @ b2
    b6 = b4 @ b2
    u = b @ (b6 @ (c[13] * b6 + c[11] * b4 + c[9] * b2)
             + c[7] * b6 + c[5] * b4 + c[3] * b2 + c[1] * ident)
    v = (b6 @ (c[12] * b6 + c[10] * b4 + c[8] * b2)
         + c[6] * b6 + c[4] * b4 + c[2] * b2 + c[0] * ident)
    e = np.linalg.solve(v - u, v + u)
    for _ in range(s):
        e = e @ e
    # Undo the balancing: exp(D^-1 A D) = D^-1 exp(A) D.
    return e * d[:, None] / d[None, :]


def zero_order_hold(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretization of x' = A x + B u with u held over ``dt``.

    Parameters
    ----------
    a : ndarray, shape (n, n)
        System matrix [1/s].
    b : ndarray, shape (n, m)
        Input matrix.
    dt : float
        Step [s], > 0.

    Returns
    -------
    phi, gamma : ndarray, shapes (n, n) and (n, m)
        x[k+1] = phi x[k] + gamma u[k].
    """
    n, m = b.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n] = a * dt
    augmented[:n, n:] = b * dt
    e = expm(augmented)
    return e[:n, :n].copy(), e[:n, n:].copy()


def with_lag(a: np.ndarray, b: np.ndarray, bandwidth_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The model with its first input passed through a first-order lag of ``bandwidth_hz``.

    The lag's output becomes the last state: x_new = [x, y], y' = w (u0 - y), w = 2 pi f, and
    the model's first input column is fed by y. The other inputs stay direct.
    """
    n, m = b.shape
    w = 2.0 * math.pi * bandwidth_hz
    a2 = np.zeros((n + 1, n + 1))
    a2[:n, :n] = a
    a2[:n, n] = b[:, 0]
    a2[n, n] = -w
    b2 = np.zeros((n + 1, m))
    b2[:n, 1:] = b[:, 1:]
    b2[n, 0] = w
    return a2, b2


def _term(coefficient: float, name: str) -> str | None:
    if coefficient == 0.0:
        return None
    if coefficient == 1.0:
        return name
    if coefficient == -1.0:
        return f"-{name}"
    return f"{coefficient!r} * {name}"


def linear_step(phi: np.ndarray, gamma: np.ndarray):
    """``step(x, u0, ..., um-1) -> [x'...]``: x' = phi x + gamma u as one straight-line function.

    ``x`` is a sequence of n floats; the result is a new list. Exact zeros are left out and
    unit factors are not multiplied (both exact), every other term is summed in index order,
    states before inputs, so the arithmetic is the same for every call.
    """
    phi = np.asarray(phi, dtype=float)
    gamma = np.asarray(gamma, dtype=float).reshape(phi.shape[0], -1)
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(gamma))):
        raise InputError("step matrices should be finite")
    n, m = gamma.shape
    states = [f"x{i}" for i in range(n)]
    inputs = [f"u{j}" for j in range(m)]
    rows = []
    for i in range(n):
        terms = [_term(float(phi[i, k]), states[k]) for k in range(n)]
        terms += [_term(float(gamma[i, j]), inputs[j]) for j in range(m)]
        terms = [t for t in terms if t is not None]
        rows.append(" + ".join(terms).replace("+ -", "- ") if terms else "0.0")
    source = (f"def step(x, {', '.join(inputs)}):\n"
              f"    {', '.join(states)}{',' if n == 1 else ''} = x\n"
              f"    return [{', '.join(rows)}]\n")
    namespace: dict = {}
    exec(compile(source, "<hil_sim.discretize.linear_step>", "exec"), namespace)  # noqa: S102
    step = namespace["step"]
    step.source = source
    return step


def friction_step(motor_column, load_column, speeds: tuple[int, int], limits: tuple[float, float],
                  iterations: int):
    """``correct(free) -> (x', f_motor, f_load)``: a step's end state with the Coulomb friction
    torques the step needs, as one straight-line function of plain floats (the rig runs it on
    every sub-step, where a loop over lists costs more than its arithmetic).

    The end speeds are linear in the two friction torques, ``w_end = free + G f`` with G from
    the mode's columns of the two shaft torques (``motor_column``, ``load_column``); each torque
    is the one that stops its shaft, clipped to its limit, solved by projected Gauss-Seidel over
    at most ``iterations`` sweeps (one exact sweep with a single friction). A shaft held by
    stiction ends exactly at rest. Every expression is :meth:`hil_sim.plant.Plant`'s former loop
    term for term, in the same order, so the result is the same float for float.
    """
    motor = [float(v) for v in motor_column]
    load = [float(v) for v in load_column]
    n = len(motor)
    i_m, i_l = speeds
    limit_m, limit_l = (float(v) for v in limits)
    g11, g12, g21, g22 = motor[i_m], load[i_m], motor[i_l], load[i_l]
    values = [motor, load, [g11, g12, g21, g22], [limit_m, limit_l]]
    if not all(math.isfinite(v) for row in values for v in row):
        raise InputError("friction step columns and limits should be finite")
    states = [f"x{i}" for i in range(n)]
    lines = [f"def correct(free):",
             f"    {', '.join(states)}{',' if n == 1 else ''} = free",
             f"    v_m = x{i_m}",
             f"    v_l = x{i_l}",
             "    f_m = f_l = 0.0",
             f"    for _ in range({iterations if limit_m and limit_l else 1}):",
             "        previous_m = f_m",
             "        previous_l = f_l"]
    if limit_m:
        lines += [f"        f_m = -(v_m + {g12!r} * f_l) / {g11!r}",
                  f"        f_m = {limit_m!r} if f_m > {limit_m!r} else "
                  f"({-limit_m!r} if f_m < {-limit_m!r} else f_m)"]
    if limit_l:
        lines += [f"        f_l = -(v_l + {g21!r} * f_m) / {g22!r}",
                  f"        f_l = {limit_l!r} if f_l > {limit_l!r} else "
                  f"({-limit_l!r} if f_l < {-limit_l!r} else f_l)"]
    lines += ["        if f_m == previous_m and f_l == previous_l:",
              "            break",
              "    if f_l:",
              "        out = [" + ", ".join(f"{s} + {a!r} * f_m + {b!r} * f_l"
                                         for s, a, b in zip(states, motor, load)) + "]",
              "    else:",
              "        out = [" + ", ".join(f"{s} + {a!r} * f_m" for s, a in zip(states, motor)) + "]"]
    if limit_m:
        lines += [f"    if {-limit_m!r} < f_m < {limit_m!r}:", f"        out[{i_m}] = 0.0"]
    if limit_l:
        lines += [f"    if {-limit_l!r} < f_l < {limit_l!r}:", f"        out[{i_l}] = 0.0"]
    lines.append("    return out, f_m, f_l")
    source = "\n".join(lines) + "\n"
    namespace: dict = {}
    exec(compile(source, "<hil_sim.discretize.friction_step>", "exec"), namespace)  # noqa: S102
    correct = namespace["correct"]
    correct.source = source
    return correct
