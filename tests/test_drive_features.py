"""The drive's speed-reference symmetrization and friction feed-forward (issue 20, item 2):
[drive] options, off by default as drives ship them."""

from __future__ import annotations

from dataclasses import replace

import pytest

from hil_sim import SCENES_DIR
from hil_sim.control import DriveEffects
from hil_sim.rig import run_scene
from hil_sim.rig.run import axis_setup, friction_feedforward, prepare
from hil_sim.scene import load_scene


def _scene(name, **drive):
    scene = load_scene(SCENES_DIR / f"{name}.toml").with_fidelity("full")
    return replace(scene, drive=replace(scene.drive, **drive))


def test_both_are_off_by_default_and_reach_the_axis():
    scene = load_scene(SCENES_DIR / "stiff_coupling.toml")
    assert not scene.drive.speed_symmetrization and not scene.drive.friction_feedforward
    run, _ = prepare(_scene("stiff_coupling", speed_symmetrization=True,
                            friction_feedforward=True))
    drive = axis_setup(run, run.effect_values.applicable).drive_effects
    assert drive.speed_symmetrization
    m = run.mechanics
    # the machine's friction at the motor: F_m + F_L r / eta (hil_sim.effects' defaults here)
    expected = (0.01 * m.motor_torque_limit
                + 0.01 * m.motor_torque_limit * m.gear_efficiency / m.gear_ratio
                * m.gear_ratio / m.gear_efficiency)
    assert friction_feedforward(run) == pytest.approx(expected, rel=1e-12)
    assert drive.friction_feedforward == friction_feedforward(run)
    with pytest.raises(ValueError, match="friction_feedforward"):
        DriveEffects(friction_feedforward=-1.0)
    with pytest.raises(ValueError, match="speed_symmetrization"):
        DriveEffects(speed_symmetrization=1)


def test_symmetrization_lowers_the_following_error_the_drive_reports():
    """The PI no longer compares the reference with an estimate half a period and a filter
    behind it: the drive's own following error falls (soft_coupling at the full model)."""
    plain = run_scene(_scene("soft_coupling"), path="fast")
    balanced = run_scene(_scene("soft_coupling", speed_symmetrization=True), path="fast")
    assert (balanced.check("following_error").value
            < 0.8 * plain.check("following_error").value)


def test_symmetrization_does_nothing_without_an_encoder(tmp_path):
    base = _scene("stiff_coupling")
    ideal = base.with_fidelity("ideal")
    a = run_scene(ideal, path="fast")
    b = run_scene(replace(ideal, drive=replace(ideal.drive, speed_symmetrization=True)),
                  path="fast")
    assert a.to_json() == b.to_json()


def test_friction_feedforward_lowers_the_tracking_error_of_a_frictional_axis():
    plain = run_scene(_scene("stiff_coupling"), path="fast")
    compensated = run_scene(_scene("stiff_coupling", friction_feedforward=True), path="fast")
    assert (compensated.check("tracking_error").value
            < 0.9 * plain.check("tracking_error").value)
