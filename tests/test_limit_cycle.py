"""The limit-cycle detector of loop_stability: coupling torque the cam's harmonics do not
explain (issue 20, item 4)."""

from __future__ import annotations

from dataclasses import replace

from hil_sim import SCENES_DIR
from hil_sim.rig import run_scene
from hil_sim.scene import load_scene


def _stiff_with_backlash(**limits):
    base = load_scene(SCENES_DIR / "stiff_coupling.toml").with_fidelity("full")
    effects = tuple((k, v) for k, v in base.mechanics.effects if k != "gear_backlash")
    scene = replace(base, mechanics=replace(base.mechanics, effects=effects))
    return replace(scene, limits=replace(scene.limits, **limits))


def test_hammering_through_the_backlash_is_a_limit_cycle_even_with_the_margins_waived():
    """The old fixed 200 Hz velocity loop on the stiff machine with a standard gearhead's
    3 arcmin: with the margin limits waived, the detector finds the hammering."""
    waived = _stiff_with_backlash(phase_margin_deg=0.0, gain_margin_db=0.0,
                                  sensitivity_peak=100.0)
    old = replace(waived, drive=replace(waived.drive, gains=(("velocity_bandwidth_hz", 200.0),)))
    report = run_scene(old, path="fast")
    loop = report.check("loop_stability")
    assert not loop.passed and "LIMIT CYCLE: coupling torque the cam's harmonics do not " \
                               "explain" in loop.detail
    assert "auto-tuning gives" in loop.detail  # what the commissioning engineer would ship


def test_the_auto_tuned_machine_has_none():
    report = run_scene(_stiff_with_backlash(), path="fast")
    loop = report.check("loop_stability")
    assert loop.passed and "LIMIT CYCLE" not in loop.detail
    assert "do not explain" in loop.detail
