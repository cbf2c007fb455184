"""The drive's commissioning (hil_sim.tuning): the loop analysis against an independent one
built with python-control from the physics, the tuner's rule, and the report's tuning."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

control = pytest.importorskip("control")

from hil_sim import SCENES_DIR, effects  # noqa: E402
from hil_sim.control import DriveEffects, Gains  # noqa: E402
from hil_sim.plant import MechanicalEffects  # noqa: E402
from hil_sim.rig.run import commission  # noqa: E402
from hil_sim.scene import load_scene  # noqa: E402
from hil_sim.tuning import (AxisLoops, MarginLimits, gap_model, loop_model,  # noqa: E402
                            margins_of)


def _scene(name: str):
    return load_scene(SCENES_DIR / f"{name}.toml")


def _values(scene):
    mechanics = scene.mechanics.build()
    return mechanics, effects.resolve(mechanics, dict(scene.mechanics.effects),
                                      dict(scene.drive.effects), scene.drive.control_rate_hz)


def _dt(scene) -> float:
    return scene.drive.cycle_s / scene.drive.substeps


# ------------------------------------------------------------------ an independent loop
def _plant_speed(mechanics, jc: float, current_hz: float | None, model: str):
    """The motor speed's response to the torque command, continuous, from the equations of the
    plant's docstring (the angle left out: the velocity loop does not feed it back)."""
    m = mechanics
    r, eta = m.gear_ratio, m.gear_efficiency
    g = r / eta
    if model == "rigid":
        j = m.reflected_inertia() + jc * r * r / eta
        a = np.array([[-m.reflected_damping() / j]])
        b = np.array([[1.0 / j]])
        c = np.array([[1.0]])
    else:
        jm, jl = m.motor_inertia + 0.5 * jc * r * r / eta, m.load_inertia + 0.5 * jc
        k, d = m.coupling_stiffness, m.coupling_damping
        # states: motor speed, twist, load speed
        a = np.array([[-(m.motor_damping + g * d * r) / jm, -g * k / jm, g * d / jm],
                      [r, 0.0, -1.0],
                      [d * r / jl, k / jl, -(d + m.load_damping) / jl]])
        b = np.array([[1.0 / jm], [0.0], [0.0]])
        c = np.array([[1.0, 0.0, 0.0]])
    plant = control.ss(a, b, c, 0.0)
    if current_hz is not None:
        w = 2.0 * math.pi * current_hz
        plant = plant * control.tf([w], [1.0, w])
    return plant


def _independent_velocity_loop(mechanics, jc, drive: DriveEffects, gains: Gains, dt: float,
                               model: str):
    """L_v from python-control's blocks: zero-order-hold plant, PI, analog notch by the
    prewarped bilinear transform, one period of delay (ideal speed feedback).

    The blocks are joined in state space: a product of transfer-function polynomials with
    poles near z = 1 loses digits (the rotary knife's 228 Hz two-mass plant, issue 21: 1.8e-5
    at 1-5 Hz through polynomials, 5e-13 through state space)."""
    assert drive.encoder_counts_per_rev is None
    plant = control.c2d(control.ss(_plant_speed(mechanics, jc, drive.current_loop_hz, model)), dt,
                        "zoh")
    pi = control.ss(control.tf([gains.velocity_kp, gains.velocity_ki * dt - gains.velocity_kp],
                               [1.0, -1.0], dt))
    loop = pi * plant
    if gains.notch_hz:
        w = 2.0 * math.pi * gains.notch_hz
        depth = gains.notch_width * 10.0 ** (-gains.notch_depth_db / 20.0)
        notch = control.tf([1.0, 2.0 * depth * w, w * w], [1.0, 2.0 * gains.notch_width * w, w * w])
        loop = loop * control.c2d(control.ss(notch), dt, "tustin", prewarp_frequency=w)
    if drive.computation_delay:
        loop = loop * control.ss(control.tf([1.0], [1.0, 0.0], dt))
    return loop


@pytest.mark.parametrize("name", ["stiff_coupling", "rotary_knife", "soft_coupling"])
def test_the_velocity_loop_is_the_one_python_control_builds_from_the_physics(name):
    scene = _scene(name)
    mechanics, values = _values(scene)
    dt = _dt(scene)
    tuning = commission(scene)
    _, plant_effects, drive = values.build(values.applicable)
    ideal_feedback = replace(drive, encoder_counts_per_rev=None)
    ours = loop_model(mechanics, dt, "two_mass", plant_effects, ideal_feedback)
    gains = tuning.gains
    theirs = _independent_velocity_loop(mechanics, plant_effects.coupling_inertia, ideal_feedback,
                                        gains, dt, "two_mass")
    # above 1 Hz: below it python-control's polynomial products near z = 1 lose digits
    band = ours.frequencies >= 1.0
    f = ours.frequencies[band]
    response = np.squeeze(control.frequency_response(theirs, 2 * np.pi * f).complex)
    velocity = ours.loops(gains)[0][band]
    assert np.max(np.abs(velocity - response) / np.abs(response)) < 1e-6
    # python-control's margins from its own response on a dense grid (an FRD): its search for
    # the crossings by polynomial roots finds spurious ones on the knife's plant with the
    # gearhead in (issue 21: gain crossovers at 302 and 310 rad/s where |L| is 1.35 and 1.29)
    omega = 2.0 * np.pi * np.logspace(-1.0, np.log10(0.499 / dt), 40000)
    sampled = control.frd(np.squeeze(control.frequency_response(theirs, omega).complex), omega)
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(sampled)
    mine = ours.velocity_margins(gains)
    assert mine.stable
    assert mine.gain_margin_db == pytest.approx(20 * math.log10(gm), abs=0.05)
    assert mine.phase_margin_deg == pytest.approx(pm, abs=0.2)
    assert mine.crossover_hz == pytest.approx(wgc / (2 * math.pi), rel=2e-3)
    assert mine.sensitivity_peak == pytest.approx(1.0 / sm, rel=5e-3)


def test_the_speed_estimate_filter_is_the_encoders():
    """With the encoder the speed the loop sees is the filtered difference quotient of the angle:
    a / (1 - (1 - a) z^-1) (1 - z^-1) / dt on the angle's response (python-control's)."""
    scene = _scene("stiff_coupling")
    mechanics, values = _values(scene)
    dt = _dt(scene)
    model, plant_effects, drive = values.build(values.applicable)
    ours = loop_model(mechanics, dt, model, plant_effects, drive)
    a = 1.0 - math.exp(-2 * math.pi * drive.velocity_filter_hz * dt)
    estimator = control.tf([a / dt, -a / dt], [1.0, -(1.0 - a)], dt)
    # the angle from the plant: the speed integrated (continuous), zero-order hold
    speed = _plant_speed(mechanics, plant_effects.coupling_inertia, drive.current_loop_hz, model)
    angle = control.c2d(speed * control.tf([1.0], [1.0, 0.0]), dt, "zoh")
    f = ours.frequencies[ours.frequencies > 1.0]
    theirs = np.squeeze(control.frequency_response(estimator * angle, 2 * np.pi * f).complex)
    assert np.max(np.abs(ours.speed[ours.frequencies > 1.0] - theirs) / np.abs(theirs)) < 1e-6


def test_the_block_formula_is_the_period_map():
    """The loop's response from its blocks equals -C (zI - A)^-1 B of the period map written
    in the order the drive runs its control law (both loops, encoder, notch, delay)."""
    scene = _scene("rotary_knife")
    mechanics, values = _values(scene)
    dt = _dt(scene)
    model, plant_effects, drive = values.build(values.applicable)
    ours = loop_model(mechanics, dt, model, plant_effects, drive)
    gains = commission(scene).gains
    assert gains.notch_hz > 0
    velocity, position = ours.loops(gains)
    cascade = velocity + gains.position_kp * ours.controller(gains) * ours.angle
    for with_position, expected in ((False, velocity), (True, cascade)):
        a, b, c = ours.open_loop_matrices(gains, with_position)
        n = a.shape[0]
        got = np.array([-(c @ np.linalg.solve(z * np.eye(n) - a, b)) for z in ours.z[::50]])
        assert np.max(np.abs(got - expected[::50]) / np.abs(expected[::50])) < 1e-8
    # 1 + L = (1 + L_v)(1 + L_p)
    assert np.allclose(1 + cascade, (1 + velocity) * (1 + position), rtol=1e-9)


def test_margins_of_a_textbook_loop():
    """An integrator with a pure delay, L = K e^{-s T} / s: |L| = 1 at w = K, PM = 90 - K T deg
    (in rad), and the phase is -180 deg at w = pi / (2 T) where GM = pi / (2 K T)."""
    k, delay = 100.0, 2e-3
    w = np.geomspace(1.0, 2e4, 200_000)
    loop = k * np.exp(-1j * w * delay) / (1j * w)
    m = margins_of(w / (2 * math.pi), loop)
    assert m.crossover_hz == pytest.approx(k / (2 * math.pi), rel=1e-6)
    assert m.phase_margin_deg == pytest.approx(90.0 - math.degrees(k * delay), abs=1e-4)
    assert m.gain_margin_db == pytest.approx(20 * math.log10(math.pi / (2 * k * delay)), abs=1e-5)


# ------------------------------------------------------------------ the tuner
SHIPPED = ["stiff_coupling", "soft_coupling", "rotary_knife", "drive_side", "cam_in"]


@pytest.mark.parametrize("name", SHIPPED)
def test_auto_tuning_meets_the_margins_on_the_full_model(name):
    tuning = commission(_scene(name))
    overall = tuning.assessment.overall
    assert tuning.source == "auto" and tuning.met and overall.stable
    assert overall.phase_margin_deg >= 45.0 and overall.gain_margin_db >= 6.0
    assert overall.sensitivity_peak <= 2.0
    assert 0 < tuning.position_bandwidth_hz <= tuning.velocity_bandwidth_hz
    # the highest bandwidth: 10 % more velocity gain breaks a limit
    loops = AxisLoops.from_setup  # noqa: F841 (the same loops are built by commission)
    assert commission(_scene(name)) == tuning  # deterministic


def test_a_higher_velocity_gain_breaks_a_margin():
    scene = _scene("stiff_coupling")
    mechanics, values = _values(scene)
    tuning = commission(scene)
    from hil_sim.tuning import full_loops
    loops = full_loops(mechanics, values, _dt(scene))
    g = tuning.gains
    stiffer = replace(g, velocity_kp=1.1 * g.velocity_kp, velocity_ki=1.21 * g.velocity_ki)
    assert not MarginLimits().met(loops.contact.velocity_margins(stiffer))


def test_the_backlash_gap_limits_the_gain_of_a_high_inertia_ratio():
    """In the gap the motor sees only its own inertia: the loop gain rises by the inertia
    ratio, and the tuner keeps the margins there too."""
    scene = _scene("soft_coupling")
    mechanics, values = _values(scene)
    model, plant_effects, drive = values.build(values.applicable)
    assert plant_effects.gear_backlash > 0
    gap = gap_model(mechanics, _dt(scene), plant_effects, drive)
    tuning = commission(scene)
    assert MarginLimits().met(gap.velocity_margins(tuning.gains))
    assert tuning.assessment.gap is not None
    without = replace(values, values=tuple(
        replace(v, value=0.0) if v.name == "gear_backlash" else v for v in values.values))
    from hil_sim.tuning import commission as tune
    free = tune(mechanics, without, _dt(scene), {}, scene.drive.feedforward)
    assert free.velocity_bandwidth_hz > tuning.velocity_bandwidth_hz


def test_scene_gains_win_and_are_reported_as_the_scenes(tmp_path):
    text = (SCENES_DIR / "stiff_coupling.toml").read_text().replace(
        "../../firmware_tables", str((SCENES_DIR / "../../firmware_tables").resolve()))
    text = text.replace("[mechanics]", "[drive.gains]\nvelocity_bandwidth_hz = 200.0\n\n[mechanics]")
    path = tmp_path / "scene.toml"
    path.write_text(text)
    tuning = commission(load_scene(path))
    assert tuning.source == "scene" and tuning.from_scene == ("velocity_bandwidth_hz",)
    mechanics = load_scene(path).mechanics.build()
    assert tuning.gains.velocity_kp == pytest.approx(mechanics.reflected_inertia() * 2 * math.pi * 200)
    # the old fixed 200 Hz: the full model's loop misses its margins (issue 20's finding)
    assert not tuning.met
    assert tuning.auto is not None and tuning.auto.met
    data = tuning.to_dict()
    for key in ("source", "velocity_kp", "velocity_ki", "position_kp", "velocity_bandwidth_hz",
                "position_bandwidth_hz", "notch_hz", "phase_margin_deg", "gain_margin_db",
                "sensitivity_peak"):
        assert key in data
    assert data["auto"]["phase_margin_deg"] >= 45.0


def test_margin_limits_are_checked():
    with pytest.raises(ValueError, match="sensitivity_peak"):
        MarginLimits(sensitivity_peak=1.0)
    with pytest.raises(ValueError, match="phase_margin_deg"):
        MarginLimits(phase_margin_deg=-1.0)
