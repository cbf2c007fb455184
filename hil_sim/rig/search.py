"""The highest master speed at which a scene passes, by bisection over rig runs."""

from __future__ import annotations

import math

from ecam.errors import InputError
from hil_sim.rig.run import run_scene
from hil_sim.scene import Scene, load_scene


def find_max_speed(scene, *, tolerance: float = 0.01, max_runs: int = 24) -> dict:
    """Highest master speed at which every check passes, by bisection.

    Parameters
    ----------
    scene : Scene or str or Path
        The scene; its master speed is the starting point (its sign is kept).
    tolerance : float
        Stop when the bracket [passing, failing] is narrower than this fraction of the
        passing speed, > 0.
    max_runs : int
        Upper bound on rig runs.

    Returns
    -------
    dict
        ``speed`` (highest passing speed found, None if none passed), ``failing_speed``
        (lowest failing speed found, None if none failed), ``unit``, ``failed_checks`` (what
        failed at ``failing_speed``), ``runs`` (speed, passed, failed checks of every run).

    Notes
    -----
    Assumes that a scene that passes at a speed passes at every lower one (true for the
    tracking, torque and following-error limits of a cam; resonance can break it: a slower
    master can put a stronger harmonic on the coupling mode, so the answer is the highest
    passing speed of the bracket the search found, not a proof that no faster speed passes).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 1):
        raise InputError(f"tolerance {tolerance!r} should be a number in (0, 1)")
    profile = scene.cam.load_profile()
    start = scene.master.units_per_second(profile.master_period)
    sign = math.copysign(1.0, start)
    runs = []

    def passes(speed: float) -> bool:
        report = run_scene(scene.with_master_speed(sign * speed))
        runs.append({"speed": sign * speed, "passed": report.passed,
                     "failed": [c.name for c in report.failed]})
        return report.passed

    low, high = _bracket(passes, abs(start), runs, max_runs // 2)
    while low is not None and high is not None and len(runs) < max_runs \
            and (high - low) > tolerance * low:
        middle = 0.5 * (low + high)
        if passes(middle):
            low = middle
        else:
            high = middle
    failed = next((r["failed"] for r in runs if high is not None and abs(r["speed"]) == high), [])
    return {"speed": None if low is None else sign * low,
            "failing_speed": None if high is None else sign * high,
            "unit": f"{profile.master_unit}/s", "failed_checks": failed, "runs": runs}


def _bracket(passes, speed: float, runs: list, max_runs: int):
    """(passing, failing) speeds around the limit, by doubling or halving from ``speed``; one
    of them None when ``max_runs`` runs found no change."""
    low, high = None, None
    if passes(speed):
        low = speed
        while len(runs) < max_runs:
            speed *= 2.0
            if not passes(speed):
                return low, speed
            low = speed
    else:
        high = speed
        while len(runs) < max_runs:
            speed /= 2.0
            if passes(speed):
                return speed, high
            high = speed
    return low, high
