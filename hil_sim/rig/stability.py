"""The drive's side of a verdict: the ``loop_stability`` check, the margins of the loop as it
runs (the run's model and effects, the drive's gains; :mod:`hil_sim.tuning`)."""

from __future__ import annotations


import numpy as np

from hil_sim.control import AxisSetup
from hil_sim.report import Check
from hil_sim.rig.plan import PreparedRun
from hil_sim.tuning import AxisLoops, MarginLimits, describe_margins


#: Whose limit each check is: the machine's (mechanics: the cam on this gear, coupling and load)
#: or the drive's (its tuning and stability, its torque), or the bus's.
CHECK_KINDS = {
    "following_error": "machine", "tracking_error": "machine", "coupling_peak_torque": "machine",
    "coupling_rms_torque": "machine", "wind_up": "machine", "resonance_excitation": "machine",
    "bus_load": "bus", "faults": "bus", "motor_saturation": "drive", "loop_stability": "drive",
    "limit_cycle": "drive",
}


def verdict_kind(name: str) -> str:
    """``"machine"``, ``"drive"`` or ``"bus"``: whose limit the check ``name`` is (a check this
    module does not know is the machine's)."""
    return CHECK_KINDS.get(name, "machine")


def margin_limits(run: PreparedRun) -> MarginLimits:
    """The scene's ``[limits]`` of the loop's margins."""
    limits = run.scene.limits
    return MarginLimits(limits.phase_margin_deg, limits.gain_margin_db, limits.sensitivity_peak)


#: A torque oscillation the cam does not explain fails the loop when its RMS exceeds this share
#: of the coupling's rated torque (a limit cycle that fatigues the coupling), or of the torque
#: the motor can put on the load when the coupling is unrated.
LIMIT_CYCLE_SHARE = 0.10
#: Whole cam periods at cruise speed the detector needs, after the settling time.
LIMIT_CYCLE_PERIODS = 2.0


def limit_cycle(run: PreparedRun, record) -> tuple[float, float, str] | None:
    """(RMS of the coupling torque the cam does not explain [N m], its limit, a phrase), or None
    when the run has too little of it at cruise speed to tell.

    The cam's harmonics are what repeats with the cam period: at a constant master speed the
    coupling torque's average at each master phase (period-synchronous averaging over the
    settled cycles at cruise, linearly interpolated between phase bins of about one bus cycle)
    is the cam's part, and what is left is not the cam's: a limit cycle of the loop, for
    example through the backlash or while the slave dwells."""
    plan = run.plan
    n = record.cycles
    period = run.cam.profile.master_period
    if n < 4 or plan.speed_units == 0.0:
        return None
    t = (np.arange(n) + 1.0) * plan.cycle_s
    master = plan.master_units[:n]
    speed = np.gradient(master) / plan.cycle_s
    cruise = np.abs(speed - plan.speed_units) <= 1e-6 * abs(plan.speed_units)
    selected = cruise & (t >= run.scene.limits.settle_s) & np.isfinite(record.coupling_torque[:n])
    samples_per_period = period / abs(plan.speed_units) / plan.cycle_s
    if np.count_nonzero(selected) < LIMIT_CYCLE_PERIODS * samples_per_period:
        return None
    phase = (master % period) / period
    bins = max(8, int(round(samples_per_period)))
    index = np.minimum((phase * bins).astype(int), bins - 1)[selected]
    torque = record.coupling_torque[:n][selected]
    counts = np.bincount(index, minlength=bins)
    means = np.bincount(index, weights=torque, minlength=bins) / np.maximum(counts, 1)
    filled = counts > 0
    centres = (np.arange(bins) + 0.5) / bins
    cam_part = np.interp(phase[selected], centres[filled], means[filled], period=1.0)
    residual = float(np.sqrt(np.mean((torque - cam_part) ** 2)))
    m = run.mechanics
    if m.coupling_rated_torque is not None:
        basis, what = m.coupling_rated_torque, "the coupling's rated torque"
    elif m.motor_torque_limit is not None:
        basis = m.motor_torque_limit * m.gear_efficiency / m.gear_ratio
        what = "the torque the motor can put on the load"
    else:
        return None
    limit = LIMIT_CYCLE_SHARE * basis
    return residual, limit, (f"coupling torque the cam's harmonics do not explain: {residual:.3g} "
                             f"N m RMS (limit {100 * LIMIT_CYCLE_SHARE:g} % of {what}, "
                             f"{limit:.3g} N m)")


def loop_stability_check(run: PreparedRun, setup: AxisSetup, record=None) -> Check:
    """Phase margin, gain margin and sensitivity peak of the velocity and position loops as the
    run's axis has them (in contact, and in the backlash gap when it runs with backlash), against
    the scene's limits; and, with the run's ``record``, a limit cycle in it
    (:func:`limit_cycle`). The value is the sensitivity peak Ms; the check passes when the loop
    is stable, all three margins hold and no limit cycle is found. A failing line says what
    auto-tuning would give."""
    limits = margin_limits(run)
    loops = AxisLoops.from_setup(setup, run.plan.cycle_s)
    assessment = loops.assess(setup.gains)
    overall = assessment.overall
    passed = limits.met(overall)
    crossover = assessment.velocity.crossover_hz
    detail = describe_margins(overall, limits)
    if crossover is not None:
        detail += f"; velocity loop crossover {crossover:.4g} Hz"
    if assessment.position.crossover_hz is not None:
        detail += f", position loop {assessment.position.crossover_hz:.4g} Hz"
    if assessment.gap is not None:
        detail += "; in the backlash gap " + describe_margins(assessment.gap, limits)
    cycle = limit_cycle(run, record) if record is not None else None
    if cycle is not None:
        residual, allowed, phrase = cycle
        if residual > allowed:
            passed = False
            phrase = "LIMIT CYCLE: " + phrase
        detail += "; " + phrase
    tuning = run.tuning
    if tuning is not None:
        detail += f"; gains: {tuning.source}"
        if not passed:
            auto = tuning if tuning.source == "auto" else tuning.auto
            if auto is not None:
                detail += (f"; the drive's tuning, not the machine: auto-tuning gives "
                           f"{auto.summary()} on the full model")
    return Check("loop_stability", overall.sensitivity_peak, limits.sensitivity_peak, passed,
                 "", detail)
