"""The drive's side of a verdict: the ``loop_stability`` check, the margins of the loop as it
runs (the run's model and effects, the drive's gains; :mod:`hil_sim.tuning`)."""

from __future__ import annotations

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


def loop_stability_check(run: PreparedRun, setup: AxisSetup) -> Check:
    """Phase margin, gain margin and sensitivity peak of the velocity and position loops as the
    run's axis has them (in contact, and in the backlash gap when it runs with backlash), against
    the scene's limits. The value is the sensitivity peak Ms; the check passes when the loop is
    stable and all three margins hold. A failing line says what auto-tuning would give."""
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
