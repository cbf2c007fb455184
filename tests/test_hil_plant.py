"""Numerical half of the hil_sim rig: matrix exponential, plants, drive loop, master, cam-in.

Every numeric assertion states its tolerance. The reference axis below is a small servo
(0.1e-3 kg m^2) through a 10:1 gear at 95 % onto a 0.02 kg m^2 load, 20-bit encoder, 1 ms bus
cycle with 16 controller periods (1/16 ms step).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ecam.errors import InputError, SimulationError
from ecam.mechanics import Mechanics
from hil_sim.control import Gains, ServoAxis
from hil_sim.master import ConstantSpeed, StartStop, cam_in
from hil_sim.plant import (RigidPlant, TwoMassPlant, choose_model, expm,
                           significant_harmonic_hz, zero_order_hold)

STEP_S = 1.0 / 16000.0
STIFFNESSES = (1e1, 1e3, 1e6, 1e9)


def axis_mechanics(stiffness=None, damping_ratio=0.0, torque_limit=10.0, efficiency=0.95):
    """The reference axis; coupling damping set from a damping ratio of the torsional mode."""
    damping = 0.0
    if stiffness is not None:
        bare = Mechanics(motor_inertia=1e-4, gear_ratio=0.1, gear_efficiency=efficiency,
                         load_inertia=0.02, coupling_stiffness=stiffness)
        j1, j2 = bare.motor_inertia_at_load(), bare.load_inertia
        damping = 2.0 * damping_ratio * math.sqrt(stiffness * j1 * j2 / (j1 + j2))
    return Mechanics(motor_inertia=1e-4, gear_ratio=0.1, gear_efficiency=efficiency,
                     motor_damping=1e-4, load_damping=0.01, coupling_stiffness=stiffness,
                     coupling_damping=damping, load_inertia=0.02, motor_torque_limit=torque_limit)


STROKE_RAD = 2.0 * math.pi * 5.0  # five motor turns (half a load turn)
RISE_S = 0.25


def cycloid(t):
    """Cycloidal rise of STROKE_RAD in RISE_S, then dwell [motor rad]."""
    u = np.clip(np.asarray(t, dtype=float) / RISE_S, 0.0, 1.0)
    return STROKE_RAD * (u - np.sin(2.0 * np.pi * u) / (2.0 * np.pi))


def run_cycloid(axis, cycles=600, offset_counts=0):
    """Stream the cycloid as CSP targets; return following errors [counts] and states."""
    cpr = axis.counts_per_motor_rad
    errors, states = [], []
    for k in range(1, cycles + 1):
        axis.cycle(offset_counts + round(float(cycloid(k * axis.cycle_s)) * cpr), 0.0)
        errors.append(axis.following_error_counts)
        states.append(axis.state)
    return np.array(errors), states


# ---------------------------------------------------------------- matrix exponential
def test_expm_matches_scipy_on_random_and_stiff_matrices():
    import scipy.linalg as scipy_linalg  # in the test extra: this check must run, not skip
    rng = np.random.default_rng(20240501)
    for n in (1, 2, 3, 4, 6, 9):
        for norm in (1e-6, 0.1, 1.0, 10.0, 60.0):
            a = rng.standard_normal((n, n)) * norm / math.sqrt(n)
            expected = scipy_linalg.expm(a)
            assert np.max(np.abs(expm(a) - expected)) <= 1e-11 * np.max(np.abs(expected))
    # The augmented ZOH matrices of the plant, from very soft to very stiff: compare entry by
    # entry relative to each entry's own scale (rows and columns differ by 1e12).
    for stiffness in STIFFNESSES:
        mechanics = axis_mechanics(stiffness, damping_ratio=0.02)
        plant = TwoMassPlant(mechanics, STEP_S)
        a = np.zeros((5, 5))
        a[:4, :4] = _two_mass_a(mechanics) * STEP_S
        a[1, 4] = STEP_S / mechanics.motor_inertia
        expected = scipy_linalg.expm(a)
        scale = np.sqrt(np.outer(np.abs(expected).max(axis=1), np.abs(expected).max(axis=0)))
        assert np.all(np.abs(plant.phi - expected[:4, :4]) <= 1e-9 * scale[:4, :4])
        assert np.all(np.abs(plant.gamma - expected[:4, 4]) <= 1e-9 * scale[:4, 4])


def _two_mass_a(m):
    g = m.gear_ratio / m.gear_efficiency
    r, k, c = m.gear_ratio, m.coupling_stiffness, m.coupling_damping
    return np.array([
        [0.0, 1.0, 0.0, 0.0],
        [0.0, -(m.motor_damping + g * c * r) / m.motor_inertia, -g * k / m.motor_inertia,
         g * c / m.motor_inertia],
        [0.0, r, 0.0, -1.0],
        [0.0, c * r / m.load_inertia, k / m.load_inertia, -(c + m.load_damping) / m.load_inertia],
    ])


@pytest.mark.parametrize("omega_t", [1e-4, 0.3, 1.0, 7.0, 100.0, 1e4])
@pytest.mark.parametrize("zeta", [0.0, 0.05])
def test_expm_oscillator_closed_form(omega_t, zeta):
    """exp of [[0, 1], [-w^2, -2 zeta w]] t against the textbook damped-oscillator solution."""
    omega, t = 3.0e3, omega_t / 3.0e3
    sigma, omega_d = zeta * omega, omega * math.sqrt(1.0 - zeta * zeta)
    c, s, decay = math.cos(omega_d * t), math.sin(omega_d * t), math.exp(-sigma * t)
    expected = decay * np.array([[c + sigma / omega_d * s, s / omega_d],
                                 [-omega * omega / omega_d * s, c - sigma / omega_d * s]])
    got = expm(np.array([[0.0, 1.0], [-omega * omega, -2.0 * zeta * omega]]) * t)
    # Entry scales differ by omega; the phase omega t carries ~omega_t * 1e-16 of rounding.
    scale = np.array([[1.0, 1.0 / omega], [omega, 1.0]])
    assert np.all(np.abs(got - expected) <= (1e-13 + 1e-15 * omega_t) * scale)


def test_expm_rejects_bad_input():
    with pytest.raises(InputError, match="square"):
        expm(np.zeros((2, 3)))
    with pytest.raises(InputError, match="finite"):
        expm(np.array([[np.nan]]))


def test_rigid_zero_order_hold_is_exact_double_integrator():
    mechanics = Mechanics(motor_inertia=2e-4, load_inertia=0.0)
    plant = RigidPlant(mechanics, STEP_S)
    j, dt = 2e-4, STEP_S
    np.testing.assert_allclose(plant.phi, [[1.0, dt], [0.0, 1.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(plant.gamma, [dt * dt / (2 * j), dt / j], rtol=1e-13)
    # A pure integrator chain, x1' = x2, x2' = x3, x3' = u: Gamma = [dt^3/6, dt^2/2, dt].
    phi, gamma = zero_order_hold(np.diag([1.0, 1.0], k=1), np.array([[0.0], [0.0], [1.0]]), 0.5)
    np.testing.assert_allclose(phi, [[1, 0.5, 0.125], [0, 1, 0.5], [0, 0, 1]], rtol=1e-15)
    np.testing.assert_allclose(gamma[:, 0], [0.125 / 6, 0.125, 0.5], rtol=1e-15)


# ------------------------------------------------------------------------- plants
@pytest.mark.parametrize("stiffness", STIFFNESSES)
@pytest.mark.parametrize("efficiency", [1.0, 0.9])
def test_two_mass_twist_rings_at_torsional_frequency(stiffness, efficiency):
    """Undamped torque-step response: twist = twist_eq (1 - cos w t), w from the mechanics."""
    mechanics = Mechanics(motor_inertia=1e-4, gear_ratio=0.1, gear_efficiency=efficiency,
                          coupling_stiffness=stiffness, load_inertia=0.02)
    expected_hz = mechanics.torsional_frequency_hz()
    plant = TwoMassPlant(mechanics, 1.0 / (50.0 * expected_hz))  # 50 samples per period
    twist = np.empty(2000)  # 40 periods
    for i in range(twist.size):
        plant.step(1.0)
        twist[i] = plant.twist
    swing = twist - 0.5 * (twist.max() + twist.min())
    crossings = _zero_crossings(swing) * plant.dt
    measured_hz = 0.5 * (len(crossings) - 1) / (crossings[-1] - crossings[0])
    # The brief asks for 1 %; the ZOH is exact, so the measured error is ~1e-15.
    assert abs(measured_hz / expected_hz - 1.0) < 1e-9


def _zero_crossings(signal):
    """Fractional sample indices where ``signal`` changes sign (linear interpolation)."""
    index = np.nonzero(np.signbit(signal[:-1]) != np.signbit(signal[1:]))[0]
    return index + signal[index] / (signal[index] - signal[index + 1])


def test_ring_frequency_matches_at_the_fixed_step_by_fft():
    """At the rig's own 1/16 ms step, the 62.7 Hz mode of a 1e3 N m/rad coupling, by FFT."""
    mechanics = axis_mechanics(1e3)
    plant = TwoMassPlant(mechanics, STEP_S)
    plant.step(1.0)  # one torque pulse, then free
    twist = np.empty(2**17)  # 8.2 s
    for i in range(twist.size):
        plant.step(0.0)
        twist[i] = plant.twist
    window = np.hanning(twist.size)
    spectrum = np.abs(np.fft.rfft((twist - twist.mean()) * window))
    peak = int(np.argmax(spectrum))
    # Parabolic interpolation of the peak bin.
    left, mid, right = np.log(spectrum[peak - 1:peak + 2])
    peak_bin = peak + 0.5 * (left - right) / (left - 2 * mid + right)
    measured_hz = peak_bin / (twist.size * STEP_S)
    assert abs(measured_hz / mechanics.torsional_frequency_hz() - 1.0) < 0.01


@pytest.mark.parametrize("stiffness", STIFFNESSES)
@pytest.mark.parametrize("efficiency", [1.0, 0.8])
def test_undamped_energy_is_conserved_at_one_step_for_any_stiffness(stiffness, efficiency):
    mechanics = Mechanics(motor_inertia=1e-4, gear_ratio=0.1, gear_efficiency=efficiency,
                          coupling_stiffness=stiffness, load_inertia=0.02)
    plant = TwoMassPlant(mechanics, STEP_S)
    plant.step(1.0)
    energy = plant.energy()
    twist_bound = math.sqrt(2.0 * energy * efficiency / stiffness)
    peak_twist = 0.0
    for _ in range(50_000):
        plant.step(0.0)
        peak_twist = max(peak_twist, abs(plant.twist))
    assert np.all(np.isfinite(plant.x))
    assert abs(plant.energy() / energy - 1.0) < 1e-8
    assert peak_twist <= twist_bound * (1.0 + 1e-8)


@pytest.mark.parametrize("stiffness", STIFFNESSES)
def test_damped_energy_never_grows(stiffness):
    plant = TwoMassPlant(axis_mechanics(stiffness, damping_ratio=0.01), STEP_S)
    plant.step(1.0)
    previous = plant.energy()
    for _ in range(5_000):
        plant.step(0.0)
        energy = plant.energy()
        assert energy <= previous * (1.0 + 1e-12)
        previous = energy


def test_rigid_coupling_torque_is_what_the_load_needs():
    mechanics = axis_mechanics(None)
    plant = RigidPlant(mechanics, STEP_S)
    plant.reset(motor_speed=100.0)
    plant.step(0.5)
    acceleration = (0.5 - mechanics.reflected_damping() * plant.motor_speed) \
        / mechanics.reflected_inertia()
    expected = 0.02 * 0.1 * acceleration + 0.01 * 0.1 * plant.motor_speed
    assert plant.coupling_torque == pytest.approx(expected, rel=1e-12)
    assert plant.twist == 0.0
    assert plant.load_angle == pytest.approx(0.1 * plant.motor_angle, rel=1e-15)


# ------------------------------------------------------------------ model choice
def test_choose_model_reasons_carry_the_numbers():
    kind, reason = choose_model(axis_mechanics(None), 5.0, 200.0)
    assert kind == "rigid" and "no coupling" in reason
    stiff = axis_mechanics(1e8)  # 19.8 kHz
    kind, reason = choose_model(stiff, 20.0, 200.0)
    assert kind == "rigid" and "1.983e+04 Hz" in reason and "2000 Hz" in reason
    kind, reason = choose_model(stiff, 2500.0, 200.0)  # the cam reaches 25 kHz x 10
    assert kind == "two_mass" and "2.5e+04 Hz" in reason
    kind, _ = choose_model(axis_mechanics(1e3), 0.0, 200.0)
    assert kind == "two_mass"
    with pytest.raises(InputError, match="factor -1.0 should be"):
        choose_model(stiff, 1.0, 1.0, factor=-1.0)


def test_significant_harmonic_of_a_pure_tone_and_a_cycloid():
    n = 1024
    phase = np.arange(n) / n
    assert significant_harmonic_hz(np.sin(2 * np.pi * 3 * phase), 0.5) == pytest.approx(6.0)
    assert significant_harmonic_hz(np.zeros(n), 0.5) == 0.0
    # Cycloidal rise and dwell: the acceleration spectrum decays; 99 % is within 10 harmonics.
    acceleration = np.where(phase < 0.5, np.sin(4 * np.pi * phase), 0.0)
    assert 1.0 < significant_harmonic_hz(acceleration, 1.0) <= 10.0


@pytest.mark.parametrize("stiffness", [1e1, 1e3, 1e6, 1e8])
def test_rigid_and_two_mass_agree_exactly_when_choose_model_says_rigid(stiffness):
    mechanics = axis_mechanics(stiffness, damping_ratio=0.01)
    rigid = ServoAxis(mechanics, model="rigid")
    two_mass = ServoAxis(mechanics, model="two_mass")
    auto = ServoAxis(mechanics, excitation_hz=40.0)  # the cycloid: 4 Hz fundamental x 10
    errors_rigid, states_rigid = run_cycloid(rigid)
    errors_two_mass, states_two_mass = run_cycloid(two_mass)
    error_gap = np.max(np.abs(errors_rigid - errors_two_mass))
    load_gap = max(abs(a["load_angle"] - b["load_angle"])
                   for a, b in zip(states_rigid, states_two_mass))
    if auto.model == "rigid":
        # 1e8 N m/rad: 19.8 kHz mode; measured: 1 count, 7e-8 rad at the load.
        assert error_gap <= 2 and load_gap < 1e-6
    else:
        # 1e3 N m/rad (62.7 Hz): measured ~100 counts and 7e-3 rad at the load.
        assert stiffness <= 1e6
        if stiffness <= 1e3:
            assert error_gap >= 50 and load_gap > 1e-3


# --------------------------------------------------------------------- drive loop
def test_feedforward_tracks_a_cycloid_with_a_tiny_following_error():
    """Rigid axis, 5 turns in 0.25 s (peak 251 rad/s = 42 000 counts per cycle).

    Measured: 46 counts (2.8e-4 rad at the motor, 0.1 % of one cycle's travel) with
    feed-forward; without it 309 800 counts.
    """
    errors, states = run_cycloid(ServoAxis(axis_mechanics(None)))
    assert np.max(np.abs(errors)) <= 60
    assert np.all(np.abs(errors[-100:]) <= 1)  # settled in the dwell
    assert max(s["peak_motor_torque"] for s in states) < 1.1  # the cycloid needs 1.02 N m
    plain = Gains.from_mechanics(axis_mechanics(None), velocity_feedforward=0.0,
                                 acceleration_feedforward=0.0)
    errors_plain, _ = run_cycloid(ServoAxis(axis_mechanics(None), plain))
    assert np.max(np.abs(errors_plain)) > 50 * np.max(np.abs(errors))


def test_velocity_offset_path_tracks_as_well():
    """vff = 0 and the cam speed sent as 0x60B1 at each target's time: measured 47 counts."""
    mechanics = axis_mechanics(None)
    axis = ServoAxis(mechanics, Gains.from_mechanics(mechanics, velocity_feedforward=0.0))
    cpr = axis.counts_per_motor_rad
    errors = []
    for k in range(1, 400):
        u = min(k * 1e-3 / RISE_S, 1.0)
        speed = STROKE_RAD / RISE_S * (1.0 - math.cos(2.0 * math.pi * u))
        axis.cycle(round(float(cycloid(k * 1e-3)) * cpr), speed * cpr)
        errors.append(axis.following_error_counts)
    assert max(map(abs, errors)) <= 60


def test_torque_limit_holds_and_the_axis_recovers():
    """0.7 N m for a move that needs 1.02 N m: clamped, no wind-up, settles in the dwell."""
    axis = ServoAxis(axis_mechanics(None, torque_limit=0.7))
    errors, states = run_cycloid(axis, cycles=900)
    assert max(s["peak_motor_torque"] for s in states) <= 0.7
    assert sum(s["saturated"] for s in states) > 10
    assert np.all(np.abs(errors[-200:]) <= 1)
    assert all(s["saturated"] == 0.0 for s in states[-200:])


@pytest.mark.parametrize("stiffness", STIFFNESSES)
def test_closed_loop_stays_bounded_for_any_stiffness(stiffness):
    axis = ServoAxis(axis_mechanics(stiffness, damping_ratio=0.01), model="two_mass")
    errors, states = run_cycloid(axis, cycles=800)
    assert all(math.isfinite(v) for s in states for v in s.values())
    assert np.all(np.abs(errors[-50:]) <= 1000)
    assert max(s["peak_motor_torque"] for s in states) <= 10.0


def test_int32_wrapping_targets_give_the_same_motion():
    plain = ServoAxis(axis_mechanics(None))
    errors_plain, _ = run_cycloid(plain, cycles=300)
    start = 2**31 - 10_000_000  # the rise crosses +2^31 and the targets wrap to negative
    wrapped = ServoAxis(axis_mechanics(None), initial_counts=start)
    cpr = wrapped.counts_per_motor_rad
    errors = []
    for k in range(1, 301):
        target = start + round(float(cycloid(k * 1e-3)) * cpr)
        wrapped.cycle((target + 2**31) % 2**32 - 2**31)
        errors.append(wrapped.following_error_counts)
        assert wrapped.position_counts == (target + 2**31) % 2**32 - 2**31 - errors[-1]
    # The big offset costs float resolution in the angle (2^31 counts ~ 2e3 rad): +-1 count.
    assert np.max(np.abs(np.array(errors) - errors_plain)) <= 1


def test_same_inputs_give_bit_identical_states():
    first = run_cycloid(ServoAxis(axis_mechanics(1e4, damping_ratio=0.02)), cycles=200)[1]
    second = run_cycloid(ServoAxis(axis_mechanics(1e4, damping_ratio=0.02)), cycles=200)[1]
    assert first == second


def test_servo_axis_reports_the_model_and_rejects_bad_input():
    axis = ServoAxis(axis_mechanics(1e3), excitation_hz=10.0)
    assert axis.model == "two_mass" and "62.71 Hz" in axis.model_reason
    assert axis.position_counts == 0 and axis.following_error_counts == 0
    assert set(axis.state) >= {"motor_angle", "load_angle", "twist", "coupling_torque",
                               "motor_torque", "saturated"}
    with pytest.raises(InputError, match="model: 'two_mass' should be 'auto' or 'rigid' when mechanics has no coupling_stiffness"):
        ServoAxis(axis_mechanics(None), model="two_mass")
    with pytest.raises(InputError, match="model: 'springy' should be one of auto, rigid, two_mass"):
        ServoAxis(axis_mechanics(None), model="springy")
    with pytest.raises(InputError, match="target_counts: 1.5 should be an integer"):
        axis.cycle(1.5)
    with pytest.raises(InputError, match="substeps: 0 should be an integer >= 1"):
        ServoAxis(axis_mechanics(None), substeps=0)


@pytest.mark.parametrize("field, value, message", [
    ("coupling_stiffness", -5.0, "coupling_stiffness: -5 should be > 0"),
    ("motor_inertia", 0.0, "motor_inertia: 0 should be > 0"),
    ("gear_efficiency", 1.2, "gear_efficiency: 1.2 should be <= 1"),
    ("load_damping", -1.0, "load_damping: -1 should be >= 0"),
    ("gear_ratio", float("nan"), "gear_ratio: nan should be finite"),
    ("motor_torque_limit", "3", "motor_torque_limit: '3' should be a number"),
])
def test_mechanics_messages_name_field_value_and_bound(field, value, message):
    fields = dict(motor_inertia=1e-4, load_inertia=0.02)
    fields[field] = value
    with pytest.raises(InputError) as raised:
        Mechanics(**fields)
    assert str(raised.value) == message


def test_mechanics_reflection_follows_the_seed():
    m = Mechanics(motor_inertia=1e-4, gear_ratio=0.1, gear_efficiency=0.8, motor_damping=1e-3,
                  load_damping=0.5, load_inertia=0.02, coupling_stiffness=1e4)
    assert m.reflected_inertia() == pytest.approx(1e-4 + 0.02 * 0.01 / 0.8, rel=1e-15)
    assert m.reflected_damping() == pytest.approx(1e-3 + 0.5 * 0.01 / 0.8, rel=1e-15)
    j1 = 0.8 * 1e-4 / 0.01
    expected = math.sqrt(1e4 * (j1 + 0.02) / (j1 * 0.02)) / (2 * math.pi)
    assert m.torsional_frequency_hz() == pytest.approx(expected, rel=1e-15)
    assert Mechanics(motor_inertia=1e-4).torsional_frequency_hz() == math.inf
    with pytest.raises(InputError, match="coupling_max_torque: 1 should be >= coupling_rated_torque 2"):
        Mechanics(motor_inertia=1e-4, coupling_rated_torque=2.0, coupling_max_torque=1.0)
    with pytest.raises(InputError, match="load_inertia: 0 should be > 0 when coupling_stiffness"):
        Mechanics(motor_inertia=1e-4, coupling_stiffness=1e4)


# ------------------------------------------------------------------------- master
def check_jerk_limited(master, t_end, max_acceleration, max_jerk, points=20_001):
    t = np.linspace(0.0, t_end, points)
    position = master.position(t)
    velocity = master.velocity(t)
    acceleration = master.acceleration(t)
    dt = t[1] - t[0]
    assert np.all(np.abs(acceleration) <= max_acceleration * (1.0 + 1e-9))
    assert np.all(np.abs(np.diff(acceleration)) <= max_jerk * dt * (1.0 + 1e-6))
    # No jumps: each position step is within the interval's speed range.
    bound = np.maximum(np.abs(velocity[:-1]), np.abs(velocity[1:])) + max_acceleration * dt
    assert np.all(np.abs(np.diff(position)) <= bound * dt * (1.0 + 1e-9) + 1e-9)
    return position, velocity


@pytest.mark.slow
@settings(max_examples=25, deadline=None, derandomize=True)
@given(speed=st.floats(1e1, 1e8).flatmap(lambda s: st.sampled_from([s, -s])),
       ramp_s=st.floats(0.01, 1.0), jerk_factor=st.floats(1.0, 100.0))
def test_start_stop_reaches_speed_within_jerk_and_acceleration_limits(speed, ramp_s,
                                                                      jerk_factor):
    max_acceleration = abs(speed) / ramp_s
    max_jerk = max_acceleration * jerk_factor / ramp_s
    master = StartStop(speed, max_acceleration, max_jerk, start_s=0.05, stop_s=3.0,
                       start_position=1000.0)
    assert master.at_speed_s < 3.0
    check_jerk_limited(master, master.stopped_s + 0.1, max_acceleration, max_jerk)
    assert master.position(0.0) == 1000.0 and master.velocity(0.04) == 0.0
    assert master.velocity(master.at_speed_s) == pytest.approx(speed, rel=1e-9)
    assert master.velocity(master.stopped_s + 0.05) == 0.0
    assert master.acceleration(master.stopped_s) == pytest.approx(0.0, abs=1e-6 * max_acceleration)


def test_stop_during_the_start_ramp_is_still_jerk_limited():
    master = StartStop(1e6, 1e7, 1e8, stop_s=0.12)  # at speed only after 0.2 s
    assert master.at_speed_s > 0.12
    _, velocity = check_jerk_limited(master, master.stopped_s + 0.05, 1e7, 1e8)
    assert velocity.max() < 1e6 and velocity[-1] == 0.0


def test_master_samples_are_int64_counts():
    master = ConstantSpeed(1234.5, start_position=-3.0)
    samples = master.sample(5, 1e-3)
    assert samples.dtype == np.int64
    assert samples.tolist() == [-3, -2, -1, 1, 2]  # -3 + 1.2345 k, rounded half to even
    assert master.sample(3, 1e-3, order=1).tolist() == [1234.5] * 3
    with pytest.raises(InputError, match="cycle_s: 0 should be > 0"):
        master.sample(3, 0.0)
    with pytest.raises(InputError, match="speed: 0 should be non-zero"):
        StartStop(0.0, 1.0, 1.0)


# ---------------------------------------------------------------------------- cam-in
MASTER_PERIOD = 2**20  # master counts per revolution


def knife_cam(master, order):
    """Rotary-knife-like cam: 1:1 on average with a +-30 % speed swing, any number of turns."""
    w = 2.0 * math.pi / MASTER_PERIOD
    amplitude = 0.3 / w
    if order == 0:
        return master + amplitude * math.sin(w * master)
    if order == 1:
        return 1.0 + amplitude * w * math.cos(w * master)
    return -amplitude * w * w * math.sin(w * master)


def check_cam_in(plan, limits):
    """No jump at either end, no reversal, limits held, monotone integer samples."""
    t_end = plan.engage_s
    speed = plan.master.speed
    engage = plan.engage_master_position
    cam_state = (knife_cam(engage, 0), knife_cam(engage, 1) * speed,
                 knife_cam(engage, 2) * speed**2)
    # Start: leaves rest without a jump.
    assert plan.position(0.0) == plan.slave_position
    assert plan.velocity(0.0) == 0.0 and plan.acceleration(0.0) == 0.0
    # Engagement: just before equals the cam, just after is the cam.
    before = t_end * (1.0 - 1e-12)
    for order, value in enumerate((plan.position, plan.velocity, plan.acceleration)):
        scale = max(abs(cam_state[order]), limits[order], 1.0)
        assert abs(value(before) - cam_state[order]) <= 1e-6 * scale
        assert abs(value(t_end * (1.0 + 1e-12)) - cam_state[order]) <= 1e-6 * scale
    t = np.linspace(0.0, t_end, 10_001)
    velocity = plan.velocity(t)
    direction = math.copysign(1.0, cam_state[1])
    assert np.min(direction * velocity) >= -1e-9 * limits[0]
    assert np.max(np.abs(velocity)) <= limits[0] * (1.0 + 1e-9)
    assert np.max(np.abs(plan.acceleration(t))) <= limits[1] * (1.0 + 1e-9)
    samples = plan.sample(int(t_end / 1e-3) + 50, 1e-3)
    assert samples.dtype == np.int64
    assert np.all(direction * np.diff(samples) >= 0)
    lo, hi = plan.position_range
    assert lo == pytest.approx(min(plan.slave_position, cam_state[0]), abs=1e-6 * abs(hi - lo))
    assert hi == pytest.approx(max(plan.slave_position, cam_state[0]), abs=1e-6 * abs(hi - lo))


@pytest.mark.parametrize("master_speed", [2.0 * MASTER_PERIOD, 50.0 * MASTER_PERIOD])
def test_cam_in_engages_without_jump_or_reversal(master_speed):
    """50 rev/s is 5.2e7 master counts/s: the high-speed case of the design brief."""
    limits = (3.0 * master_speed, 100.0 * master_speed, 1e4 * master_speed)
    plan = cam_in(knife_cam, slave_position=12_345.0, master_position=0.0,
                  master_speed=master_speed, engage_master_position=3.0 * MASTER_PERIOD,
                  max_velocity=limits[0], max_acceleration=limits[1], max_jerk=limits[2])
    assert plan.engage_s == pytest.approx(3.0 * MASTER_PERIOD / master_speed, rel=1e-9)
    check_cam_in(plan, limits)
    # As a function of master position the cam-in joins the cam with matching slope.
    engage = 3.0 * MASTER_PERIOD
    assert plan.slave(engage * (1 - 1e-12), 1) == pytest.approx(knife_cam(engage, 1), rel=1e-6)


def test_cam_in_backwards_master():
    speed = -4.0 * MASTER_PERIOD
    limits = (3.0 * abs(speed), 100.0 * abs(speed), 1e4 * abs(speed))
    plan = cam_in(knife_cam, 0.0, 0.0, speed, -2.5 * MASTER_PERIOD, *limits)
    check_cam_in(plan, limits)


def test_cam_in_population_either_plans_cleanly_or_says_why():
    """Fixed-seed population: every plan returned holds the invariants; failures raise."""
    rng = np.random.default_rng(7)
    planned = 0
    for _ in range(60):
        speed = float(rng.uniform(0.5, 60.0)) * MASTER_PERIOD * float(rng.choice([-1, 1]))
        limits = (float(rng.uniform(1.4, 4.0)) * abs(speed),
                  float(rng.uniform(5.0, 200.0)) * abs(speed),
                  float(rng.uniform(100.0, 1e5)) * abs(speed))
        engage = math.copysign(float(rng.uniform(0.2, 6.0)) * MASTER_PERIOD, speed)
        slave_position = float(rng.uniform(-2.0, 1.0)) * MASTER_PERIOD * math.copysign(1, speed)
        try:
            plan = cam_in(knife_cam, slave_position, 0.0, speed, engage, *limits)
        except (SimulationError, InputError) as error:
            assert str(error)  # a reason, never a silent bad plan
            continue
        planned += 1
        check_cam_in(plan, limits)
    assert planned >= 20


def test_cam_in_refuses_what_it_cannot_do():
    limits = (3e7, 1e9, 1e12)
    with pytest.raises(InputError, match="engage_master_position: -1 should be ahead of master_position 0 for master_speed 1000000"):
        cam_in(knife_cam, 0.0, 0.0, 1e6, -1.0, *limits)
    with pytest.raises(SimulationError, match="engage further ahead"):
        cam_in(knife_cam, 0.0, 0.0, 1e7, 1e4, *limits)
    with pytest.raises(SimulationError, match="reverse"):
        # The cam runs forward but sits behind the slave: it would have to back up.
        cam_in(knife_cam, 10.0 * MASTER_PERIOD, 0.0, 1e6, MASTER_PERIOD, *limits)
    with pytest.raises(SimulationError, match="velocity reverses"):
        # Just behind the cam but too close to reach its speed going forward only: ruckig's
        # time-optimal answer backs up first, which the check on its profile catches.
        engage = 2.0 * MASTER_PERIOD
        cam_in(knife_cam, knife_cam(engage, 0) - 1000.0, 0.0, 1e6, engage, 3e6, 1e8, 1e11)
    with pytest.raises(InputError, match="max_velocity: 10000000 should be >= the cam velocity"):
        cam_in(knife_cam, 0.0, 0.0, 1e8, MASTER_PERIOD, 1e7, 1e9, 1e12)
    with pytest.raises(SimulationError, match="max_position"):
        cam_in(knife_cam, 0.0, 0.0, 1e6, 2 * MASTER_PERIOD, *limits,
               max_position=MASTER_PERIOD)
