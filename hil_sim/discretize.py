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


def hold_trajectory(a: np.ndarray, b: np.ndarray, dt: float, samples: int) -> np.ndarray:
    """``[Phi(t), Gamma(t)]`` at ``t = k dt / samples``, k = 0..samples: the state's response to
    the state and to inputs held since t = 0, shape (samples + 1, n, n + m).

    The powers of one exact step of ``dt / samples`` (:func:`zero_order_hold`), so the sampled
    trajectory is the one a plant stepping at that rate follows.
    """
    n, m = b.shape
    phi, gamma = zero_order_hold(a, b, dt / samples)
    step = np.zeros((n + m, n + m))
    step[:n, :n], step[:n, n:] = phi, gamma
    step[n:, n:] = np.eye(m)
    power = np.eye(n + m)
    out = np.empty((samples + 1, n, n + m))
    for k in range(samples + 1):
        out[k] = power[:n]
        power = step @ power
    return out


def bow(rows: np.ndarray) -> np.ndarray:
    """The largest distance of sampled coefficient rows from the chord between their first and
    last samples, per coefficient: ``max_k |r_k - ((1 - k/K) r_0 + k/K r_K)|``.

    ``rows`` has shape (K + 1, p): a linear reading of the state (a shaft's speed) as a
    function of time over a step, one coefficient per entry of [x, u]. Then, for any x and u,
    ``|reading(t_k) - chord(t_k)| <= sum_j bow_j |z_j|``: a reading whose values at both ends
    exceed that sum, with one sign, keeps that sign at every sample in between.
    """
    rows = np.asarray(rows, dtype=float)
    count = rows.shape[0] - 1
    share = (np.arange(count + 1) / count)[:, None]
    chord = (1.0 - share) * rows[0] + share * rows[-1]
    return np.abs(rows - chord).max(axis=0)


def sliding_step(phi: np.ndarray, gamma: np.ndarray, speeds: tuple[int, int],
                 limits: tuple[float, float], ratio: float, bows: np.ndarray,
                 stiffness: float, gear: float):
    """``slide(x, torque) -> (x', f_motor, f_load)`` or None, for the two-mass model (state
    [motor angle, motor speed, twist, load speed] and the current loop's torque when modelled;
    inputs torque command, motor friction, load friction): one whole step with each Coulomb
    friction at its full value against its shaft's motion, when no frictional shaft can stop
    or reverse inside the step; None when one might (the caller sub-steps then).

    While a shaft slides one way, its friction is a constant input, and the whole step is the
    linear model's exact step with it held (sub-steps would give the same state). ``bows``
    (shape (2, 7), :func:`bow` of each frictional shaft's speed over the step, in the
    coordinates motor speed, relative speed ``ratio * motor speed - load speed``, twist, motor
    torque (the current loop's state, 0 without), torque command, motor friction, load friction)
    bound how far the speed can stray from the straight line between its two ends; the step is
    taken when both ends lie beyond that bound, on the same side of zero. The relative speed
    stands in for the load speed because the common motion of both shafts does not ring the
    coupling mode: its bow is small, where the load speed's alone is not.

    And while both shafts are at rest (held by stiction, each speed exactly 0) and each
    friction can hold its shaft for the whole step, nothing moves but the current loop's
    torque: the step is exact then too. The spring holds its twist (``stiffness`` k: the load
    needs ``|k twist| < F_L``), and the motor needs ``|T_m(t) - gear k twist| < F_m`` with
    ``gear`` g = r / eta, at both ends of the step, as the motor torque moves monotonically
    between them (a first-order lag, or held without one).
    """
    phi = np.asarray(phi, dtype=float)
    if phi.shape not in ((4, 4), (5, 5)):
        raise InputError(f"phi shape {phi.shape} should be (4, 4) or (5, 5) (the two-mass model)")
    gamma = np.asarray(gamma, dtype=float).reshape(phi.shape[0], 3)
    bows = np.asarray(bows, dtype=float).reshape(2, 7)
    values = [phi, gamma, bows, np.asarray(limits, dtype=float), np.asarray([ratio])]
    if not all(np.all(np.isfinite(v)) for v in values):
        raise InputError("sliding step matrices, bounds and limits should be finite")
    n = phi.shape[0]
    i_m, i_l = speeds
    limit_m, limit_l = (float(v) for v in limits)
    states = [f"x{i}" for i in range(n)]
    lines = ["def slide(x, torque):",
             f"    {', '.join(states)}{',' if n == 1 else ''} = x"]
    if limit_m and limit_l:
        spring = f"{float(stiffness)!r} * x2"
        lines += [f"    if x{i_m} == 0.0 and x{i_l} == 0.0:",
                  f"        spring = {spring}",
                  f"        if not {-limit_l!r} < spring < {limit_l!r}:",
                  "            return None",
                  f"        reflected = {float(gear)!r} * spring"]
        if n == 5:  # the current loop's torque over the step, exactly as the linear step has it
            lag = " + ".join(t for t in (_term(float(phi[4, 4]), "x4"),
                                         _term(float(gamma[4, 0]), "torque")) if t)
            lines += [f"        applied = {lag or '0.0'}",
                      "        start = x4 - reflected",
                      "        end = applied - reflected",
                      f"        if not ({-limit_m!r} < start < {limit_m!r} "
                      f"and {-limit_m!r} < end < {limit_m!r}):",
                      "            return None",
                      "        return [x0, 0.0, x2, 0.0, applied], -end, -spring"]
        else:
            lines += ["        end = torque - reflected",
                      f"        if not {-limit_m!r} < end < {limit_m!r}:",
                      "            return None",
                      "        return [x0, 0.0, x2, 0.0], -end, -spring"]
    for shaft, index, limit in (("m", i_m, limit_m), ("l", i_l, limit_l)):
        if limit:
            lines += [f"    if x{index} > 0.0:", f"        f_{shaft} = {-limit!r}",
                      f"    elif x{index} < 0.0:", f"        f_{shaft} = {limit!r}",
                      "    else:", "        return None"]
        else:
            lines.append(f"    f_{shaft} = 0.0")
    rows = []
    for i in range(n):
        terms = [_term(float(phi[i, k]), states[k]) for k in range(n)]
        terms += [_term(float(gamma[i, j]), name)
                  for j, name in enumerate(("torque", "f_m", "f_l"))]
        terms = [t for t in terms if t is not None]
        rows.append(" + ".join(terms).replace("+ -", "- ") if terms else "0.0")
    lines.append(f"    out = [{', '.join(rows)}]")
    magnitudes = [f"abs(x{i_m})", f"abs({ratio!r} * x{i_m} - x{i_l})", "abs(x2)",
                  "abs(x4)" if n == 5 else "0.0", "abs(torque)"]
    for shaft, index, limit, row in (("m", i_m, limit_m, bows[0]), ("l", i_l, limit_l, bows[1])):
        if not limit:
            continue
        constant = float(row[5] * limit_m + row[6] * limit_l)
        bound = " + ".join([repr(constant)] + [f"{float(c)!r} * {v}"
                                                for c, v in zip(row[:5], magnitudes) if c])
        lines += [f"    bound = {bound}",
                  f"    end = out[{index}]",
                  f"    if f_{shaft} < 0.0:",
                  f"        if x{index} <= bound or end <= bound:",
                  "            return None",
                  f"    elif -x{index} <= bound or -end <= bound:",
                  "        return None"]
    lines.append("    return out, f_m, f_l")
    source = "\n".join(lines) + "\n"
    namespace: dict = {}
    exec(compile(source, "<hil_sim.discretize.sliding_step>", "exec"), namespace)  # noqa: S102
    slide = namespace["slide"]
    slide.source = source
    return slide
