"""The highest master speed at which a scene passes.

Every trial is the scene at one speed, run long enough to mean something: until the master
has reached its cruise speed (the end of a start ramp, a cam-in's engagement) and the checks'
settling time is over, then :data:`PERIODS_AT_CRUISE` whole cam periods at that speed. A trial
that cannot run at all (a cam-in that cannot engage in time, a master too fast for the bus
cycle) is a failed speed, with its reason, not the end of the search.

The search brackets the limit by doubling or halving from the scene's speed, then bisects, on
the bus-free path (:mod:`hil_sim.rig.fast`) with every effect on (the full model, which the
default model matches within its proof). The rig is deterministic, but close to a limit a check
does not move smoothly with the speed (sub-count set points, where in the cycle the worst sample
falls): once the bracket is a few percent wide the search measures that scatter of the limiting
check across the bracket (a check with a limit of 0 in its own unit, and where the verdict flips
back, the speeds it flips over) and stops refining at the speed resolution it allows; the
samples narrow the bracket, and a speed is never given above a trial that failed. The speed found
is then confirmed over CANopen with the scene's own fidelity; should it fail there, the search
steps down.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ecam.errors import EcamError, InputError
from ecam.validate import fail, integer, number
from hil_sim.rig.cam import compile_cam
from hil_sim.rig.plan import cruise_s
from hil_sim.rig.run import commission, run_scene
from hil_sim.rig.stability import verdict_kind
from hil_sim.scene import DurationSpec, Scene, load_scene

#: Whole cam periods each trial runs at its cruise speed, after the master got there.
PERIODS_AT_CRUISE = 3
#: The longest trial the search runs [cycles]: slower speeds than that allows are not tried.
MAX_TRIAL_CYCLES = 200_000
#: Bracket width (as a share of the speed) at which the scatter is measured.
_NOISE_BRACKET = 0.04
_NOISE_SAMPLES = 5
_CONFIRM_STEPS = 4


def trial_scene(scene: Scene, speed: float) -> Scene:
    """The scene at ``speed`` [master units/s], run until cruise and the settling time, then
    :data:`PERIODS_AT_CRUISE` periods."""
    at_speed = scene.with_master_speed(speed)
    cam = compile_cam(at_speed)
    start = max(cruise_s(at_speed, cam), at_speed.limits.settle_s)
    seconds = start + PERIODS_AT_CRUISE * cam.profile.master_period / abs(speed)
    cycles = math.ceil(seconds / scene.drive.cycle_s - 1e-9)
    if cycles > MAX_TRIAL_CYCLES:
        raise TrialTooLong(f"a trial at {abs(speed):.6g} {cam.profile.master_unit}/s needs "
                           f"{cycles} cycles, more than the search's {MAX_TRIAL_CYCLES}")
    return replace(at_speed, duration=DurationSpec(seconds=seconds))


class TrialTooLong(InputError):
    """A speed so slow that its trial would run longer than :data:`MAX_TRIAL_CYCLES`."""


class SceneTrials:
    """What the search varies and runs for a scene: the scene at a speed, commissioned once (a
    machine's trials are :class:`hil_sim.rig.machine_search.MachineTrials`, the same search)."""

    def __init__(self, scene: Scene):
        self.scene = scene

    def profile(self):
        """The cam profile whose master unit and period the speed is given in."""
        return self.scene.cam.load_profile()

    def start_speed(self, profile) -> float:
        """The scene's own master speed [master units/s]."""
        return self.scene.master.units_per_second(profile.master_period)

    def commission(self):
        return commission(self.scene)

    def run(self, speed: float, path: str, tuning):
        """The trial at ``speed``: bus-free with every effect on (ideal stays ideal), over
        CANopen with the scene's own fidelity."""
        candidate = trial_scene(self.scene, speed)
        if path == "fast":
            candidate = candidate.with_fidelity("ideal" if self.scene.fidelity == "ideal"
                                                else "full")
        return run_scene(candidate, path=path, tuning=tuning)

    def simulated_s(self, report) -> float:
        return report.summary["simulated_s"]

    def limiting(self, check) -> dict:
        """Whose limit the limiting check is: the machine's (mechanics) or the drive's."""
        return {"limiting_kind": verdict_kind(check.name)}


def find_max_speed(scene, *, tolerance: float = 0.01, max_runs: int = 40, progress=None) -> dict:
    """Highest master speed at which every check passes.

    Parameters
    ----------
    scene : Scene or str or Path
        The scene; its master speed is the starting point (its sign is kept).
    tolerance : float
        Stop when the bracket [passing, failing] is narrower than this share of the passing
        speed (or than the measured resolution, if that is coarser), 0 < tolerance < 1.
    max_runs : int
        Upper bound on bus-free trials, >= 4.
    progress : callable, optional
        Called with one line of text per trial.

    Returns
    -------
    dict
        ``speed`` (highest passing speed, confirmed over CANopen; None if none passed),
        ``unit``, ``periods_per_minute``, ``failing_speed`` (lowest failing speed, None if
        none failed), ``failed_checks`` and ``limiting_check`` (the failing speed's failed
        checks, and the line of the one that failed most), ``limiting_kind`` (``"machine"``,
        ``"drive"`` or ``"bus"``: whose limit that check is), ``resolution`` (the speed
        resolution the search stopped at, and ``resolution_reason``), ``trial_seconds`` (how
        long each trial ran at the found speed), ``confirmed`` (the CANopen run at ``speed``
        passed), ``runs`` (every trial: ``speed``, ``passed``, ``failed``, ``path``, and
        ``reason`` for a trial that could not run).

    Notes
    -----
    Assumes that a scene that passes at a speed passes at every lower one (true for the
    tracking, torque and following-error limits of a cam; resonance can break it: a slower
    master can put a stronger harmonic on the coupling mode, so the answer is the highest
    passing speed of the bracket found, not a proof that no faster speed passes).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    return search_speed(SceneTrials(scene), tolerance=tolerance, max_runs=max_runs,
                        progress=progress)


def search_speed(trials, *, tolerance: float = 0.01, max_runs: int = 40, progress=None) -> dict:
    """:func:`find_max_speed` of whatever ``trials`` runs (:class:`SceneTrials`, or a machine's
    :class:`hil_sim.rig.machine_search.MachineTrials`): ``profile()``, ``start_speed(profile)``,
    ``commission()``, ``run(speed, path, tuning)`` (a report with ``passed``, ``failed``,
    ``checks``, ``check(name)``), ``simulated_s(report)`` and ``limiting(check)`` (the result's
    keys naming whose limit the limiting check is)."""
    tolerance = number("tolerance", tolerance, minimum=0.0, strict=True)
    if tolerance >= 1.0:
        raise fail("tolerance", tolerance, "< 1 (a share of the passing speed)")
    max_runs = integer("max_runs", max_runs, minimum=4, maximum=10_000)
    profile = trials.profile()
    unit = profile.master_unit
    start = trials.start_speed(profile)
    sign = math.copysign(1.0, start)
    # commissioned once, on the full model, as a machine is: every trial runs the same drive
    tuning = trials.commission()
    runs: list[dict] = []
    reports: dict = {}

    def trial(speed: float, path: str = "fast"):
        """Run the scene at ``speed``; record the run; return its report (None: not runnable)."""
        try:
            report = trials.run(sign * speed, path, tuning)
        except TrialTooLong:
            raise
        except EcamError as exc:  # an infeasible trial: a failed speed, and why
            runs.append({"speed": sign * speed, "passed": False, "failed": [], "path": path,
                         "reason": str(exc)})
            _tell(progress, runs, unit, f"cannot run: {exc}")
            return None
        runs.append({"speed": sign * speed, "passed": report.passed,
                     "failed": [c.name for c in report.failed], "path": path})
        reports[(speed, path)] = report
        _tell(progress, runs, unit, "passes" if report.passed else
              "fails " + ", ".join(c.name for c in report.failed))
        return report

    def passes(speed: float) -> bool:
        report = trial(speed)
        return report is not None and report.passed

    try:
        low, high = _bracket(passes, abs(start), runs, max_runs)
    except TrialTooLong as exc:  # halved below what a trial can cover: nothing passes
        low, high = None, min((abs(r["speed"]) for r in runs), default=abs(start))
        if progress is not None:
            progress(f"search stops: {exc}")
    resolution = tolerance * (low or 0.0)
    why = f"the search's tolerance, {100 * tolerance:.3g} % of the passing speed"
    measured = False
    while low is not None and high is not None and len(runs) < max_runs:
        if not measured and high - low <= _NOISE_BRACKET * low:
            measured = True
            noise, note, samples = _resolution(trial, low, high, reports)
            if noise is not None and noise > resolution:
                resolution, why = noise, note
            elif note is not None:
                why += f" ({note})"
            # the samples narrow the bracket: the first failing one, the highest passing below it
            low, high = _narrowed(low, high, samples)
        if high - low <= max(resolution, tolerance * low):
            break
        middle = 0.5 * (low + high)
        if passes(middle):
            low = middle
        else:
            high = middle
    if low is not None:
        low, high, flipped = _monotone(runs, low, high)
        if tolerance * low > resolution:  # relative: of the speed found, not of a first bracket
            resolution = tolerance * low
            if not why.startswith("the search's tolerance"):
                why = (f"the search's tolerance, {100 * tolerance:.3g} % of the passing speed, "
                       f"coarser than {why}")
        if flipped is not None and flipped[0] > resolution:
            resolution, why = flipped
    confirmed = False
    if low is not None:
        width = max(high - low if high is not None else tolerance * low, tolerance * low)
        for _ in range(_CONFIRM_STEPS):
            report = trial(low, path="canopen")
            if report is not None and report.passed:
                confirmed = True
                break
            high, low = low, low - width
            if low <= 0.0:
                low = None
                break
    return _result(trials, profile, sign, low, high, confirmed, resolution, why, runs, reports)


def _tell(progress, runs: list, unit: str, what: str) -> None:
    if progress is not None:
        run = runs[-1]
        progress(f"trial {len(runs)}: {run['speed']:.6g} {unit}/s ({run['path']}) {what}")


def _bracket(passes, speed: float, runs: list, max_runs: int):
    """(passing, failing) speeds around the limit, by doubling or halving from ``speed``; one
    of them None when the runs ran out first."""
    low, high = None, None
    limit = max(2, max_runs // 2)
    if passes(speed):
        low = speed
        while len(runs) < limit:
            speed *= 2.0
            if not passes(speed):
                return low, speed
            low = speed
    else:
        high = speed
        while len(runs) < limit:
            speed /= 2.0
            if passes(speed):
                return speed, high
            high = speed
    return low, high


def _limiting(report) -> object:
    """The failed check that failed most (largest value / limit; a limit of 0 exceeded counts
    as most), or, when all passed, the one closest to its limit."""
    failed = report.failed
    if failed:
        return max(failed, key=lambda c: math.inf if c.ratio is None else c.ratio)
    candidates = [c for c in report.checks if c.ratio is not None]
    return max(candidates, key=lambda c: c.ratio) if candidates else None


def _resolution(trial, low: float, high: float, reports: dict):
    """(speed resolution or None, why, samples) from the scatter of the limiting check across
    the bracket: trials at evenly spaced speeds (``samples``: (speed, passed) of each, the
    trials' own verdicts).

    Two measures, the coarser one wins: a straight line through the check's value (its ratio to
    the limit; for a limit of 0, its value in its own unit, as the fidelity's comparison reads
    it: a percent point of clamped cycles, one fault), twice the residual's deviation over the
    line's slope; and where the verdict flips back (a failing speed below a passing one), the
    span of the speeds where it flips plus the samples' spacing. None when neither shows a
    scatter (``why`` then says what was measured)."""
    speeds = np.linspace(low, high, _NOISE_SAMPLES + 2)[1:-1]
    spacing = float(speeds[1] - speeds[0])
    failing = reports.get((high, "fast"))
    limiting = _limiting(failing) if failing is not None else None
    if limiting is None or limiting.limit is None:
        return None, None, []
    name = limiting.name
    scale = abs(limiting.limit) if limiting.limit else 1.0
    values, samples = [], []
    for speed in speeds:
        report = trial(float(speed))
        if report is None:
            return None, None, samples
        values.append(report.check(name).value)
        samples.append((float(speed), report.passed))
    measures = []
    flips = [s for s, ok in samples if ok and any(f < s for f, fine in samples if not fine)]
    if flips:
        first_fail = min(f for f, fine in samples if not fine)
        span = max(flips) - first_fail + spacing
        measures.append((span, f"the verdict flips back between neighbouring speeds: fails at "
                               f"{first_fail:.6g}, passes at {max(flips):.6g}, worth {span:.3g} "
                               f"in speed"))
    values = np.array([math.nan if v is None else v / scale for v in values], dtype=float)
    what = "of its limit" if limiting.limit else (
        "percent points" if limiting.unit == "%" else limiting.unit)
    if np.all(np.isfinite(values)):
        slope, offset = np.polyfit(speeds, values, 1)
        scatter = float(np.std(values - (slope * speeds + offset), ddof=2))
        if slope > 0.0 and scatter > 0.0:
            amount = f"{100 * scatter:.2g} % {what}" if limiting.limit else f"{scatter:.2g} {what}"
            measures.append((2.0 * scatter / slope,
                             f"the scatter of {name} between neighbouring speeds: +-{amount}, "
                             f"worth {2.0 * scatter / slope:.3g} in speed"))
    if measures:
        resolution, why = max(measures)
        return resolution, why, samples
    return None, (f"{name} showed no scatter over {len(samples)} trials {spacing:.3g} apart"), samples


def _monotone(runs: list, low: float, high: float | None):
    """(low, high, (resolution, why) or None): when some bus-free trial failed below a speed
    that passed (the verdict flips back near the limit), the answer is the highest passing
    speed below the lowest failing one, and the speeds the verdict flips over are the
    resolution the search can claim."""
    fast = [(abs(r["speed"]), r["passed"]) for r in runs if r["path"] == "fast"]
    fails = [s for s, ok in fast if not ok]
    if not fails or low <= min(fails):
        return low, high, None
    first_fail = min(fails)
    below = [s for s, ok in fast if ok and s < first_fail]
    if not below:
        return low, high, None
    span = low - max(below)
    return max(below), first_fail, (span, (
        f"the verdict flips back near the limit: a trial failed at {first_fail:.6g} and one "
        f"passed at {low:.6g}, so the speed is given below the failure, to {span:.3g}"))


def _narrowed(low: float, high: float, samples: list) -> tuple[float, float]:
    """The bracket after the noise samples: the first failing sample is the new failing speed,
    the highest passing one below it the new passing speed."""
    fails = [s for s, ok in samples if not ok]
    first_fail = min(fails, default=high)
    passes = [s for s, ok in samples if ok and s < first_fail]
    return max(passes, default=low), first_fail


def _result(trials, profile, sign, low, high, confirmed, resolution, why, runs, reports) -> dict:
    unit = profile.master_unit
    failed_report = reports.get((high, "fast")) if high is not None else None
    limiting = _limiting(failed_report) if failed_report is not None else None
    failing_run = next((r for r in runs if high is not None and abs(r["speed"]) == high
                        and r["path"] == "fast"), {})
    failed = failing_run.get("failed", [])
    speed = None if low is None else sign * low
    trial_seconds = None
    if low is not None:
        canopen = reports.get((low, "canopen"))
        trial_seconds = trials.simulated_s(canopen) if canopen is not None else None
    out = {
        "speed": speed, "unit": f"{unit}/s",
        "periods_per_minute": None if speed is None else 60.0 * speed / profile.master_period,
        "failing_speed": None if high is None else sign * high,
        "failed_checks": failed,
        # a speed at which the scene could not run at all is limited by why, in its words
        "limiting_check": (limiting.line() if limiting is not None else
                           f"cannot run: {failing_run['reason']}" if "reason" in failing_run else None),
        "limiting_kind": None,
        "resolution": resolution, "resolution_reason": why,
        "periods_at_cruise": PERIODS_AT_CRUISE, "trial_seconds": trial_seconds,
        "confirmed": confirmed, "runs": runs,
    }
    if limiting is not None:  # whose limit it is: the machine's (mechanics) or the drive's
        out.update(trials.limiting(limiting))
    return out
