"""Mechanics of the geared-system seed and the two-mass torsional mode."""
import math

import numpy as np
import pytest

from ecam import InputError, mechanics


def test_reflected_inertia_and_damping_follow_the_seed():
    r = 20.0 / 80.0  # R_pinion / R_gear
    assert mechanics.reflected_inertia(2.0, r, 0.9) == pytest.approx(2.0 * r**2 / 0.9)
    # efficiency divides only the reflected term
    assert mechanics.reflected_damping(0.01, 0.4, r, 0.9) == pytest.approx(0.01 + 0.4 * r**2 / 0.9)


def test_input_torque_equals_equivalent_system():
    """T_in = J_eq w_dot_in + b_eq w_in, written out from the seed's first equation."""
    r, eta, j_load, b_in, b_out = 0.25, 0.8, 3.0, 0.02, 0.5
    w_in = np.linspace(-10, 10, 8)
    a_in = np.linspace(100, -50, 8)
    w_out, a_out = r * w_in, r * a_in
    # (b_out w_out + J_load w_out_dot) w_out = eta (T_in - b_in w_in) w_in
    seed = (b_out * w_out + j_load * a_out) * (w_out / w_in) / eta + b_in * w_in
    ours = mechanics.input_torque(w_in, a_in, load_inertia=j_load, ratio=r, efficiency=eta,
                                  input_damping=b_in, output_damping=b_out)
    np.testing.assert_allclose(ours, seed, rtol=1e-12)


def test_two_mass_frequency():
    k, j1, j2 = 1.0e4, 1e-3, 4e-3
    assert mechanics.two_mass_frequency(k, j1, j2) == pytest.approx(math.sqrt(k * (j1 + j2) / (j1 * j2)))
    # equal inertias: sqrt(2k/J)
    assert mechanics.two_mass_frequency(k, j1, j1) == pytest.approx(math.sqrt(2 * k / j1))


def test_peak_torque_check_finds_the_largest_magnitude():
    check = mechanics.peak_torque_check([1.0, -12.0, 5.0], 20.0)
    assert (check.name, check.value, check.limit, check.unit, check.sample) == \
        ("coupling_peak_torque", 12.0, 20.0, "N m", 1)
    assert check.passed
    assert not mechanics.peak_torque_check([1.0, -12.0, 5.0], 10.0).passed
    unrated = mechanics.peak_torque_check([1.0], None)
    assert unrated.limit is None and unrated.passed


def test_rms_torque_check_measures_the_continuous_load():
    t = np.linspace(0.0, 1.0, 1000, endpoint=False)
    check = mechanics.rms_torque_check(12.0 * np.sin(2 * np.pi * 5 * t), 10.0)
    assert check.value == pytest.approx(12.0 / math.sqrt(2.0), rel=1e-12)
    assert check.passed  # 8.49 N m RMS although the peak (12 N m) is over the rating
    assert not mechanics.rms_torque_check([12.0, -12.0], 10.0).passed


def test_wind_up_check_in_each_of_its_three_ways():
    rigid = mechanics.wind_up_check(0.05, stiffness=None, peak_torque=12.0)
    assert (rigid.value, rigid.detail, rigid.passed) == (0.0, "no coupling", True)
    computed = mechanics.wind_up_check(0.05, stiffness=1e4, peak_torque=12.0)
    assert computed.value == pytest.approx(math.degrees(12.0 / 1e4), rel=1e-15)
    assert computed.detail == "peak torque / stiffness" and not computed.passed
    measured = mechanics.wind_up_check(None, stiffness=1e4, peak_torque=12.0, twist=[1e-4, -3e-4])
    assert measured.value == pytest.approx(math.degrees(3e-4), rel=1e-15)
    assert measured.detail == "coupling twist" and measured.passed  # no limit: informational


def test_resonance_excitation_check_reads_the_harmonics_next_to_the_mode():
    spectrum = np.array([0.0, 10.0, 1.0, 0.5, 0.2])  # harmonics 0..4
    check = mechanics.resonance_excitation_check(2.5 * 3.0, 3.0, spectrum, 5.0)
    # mode at 2.5 x the cycle: harmonics 2 and 3, the stronger carries 1/10 of harmonic 1
    assert check.value == pytest.approx(10.0, rel=1e-15) and not check.passed
    assert "harmonic 2 carries 10 %" in check.detail and "2.5 x the 3 Hz cam cycle" in check.detail
    beyond = mechanics.resonance_excitation_check(30.0, 3.0, spectrum, 5.0)
    assert beyond.value == 0.0 and "above the 4 harmonics resolved" in beyond.detail
    rigid = mechanics.resonance_excitation_check(math.inf, 3.0, spectrum, 5.0)
    assert rigid.value is None and rigid.limit is None and rigid.passed
    assert mechanics.torsional_harmonic(math.inf, 3.0) is None
    assert mechanics.torsional_harmonic(7.5, 3.0) == 2.5


def test_residual_vibration_smaller_for_smoother_laws():
    import ecam

    f, t = 40.0, 0.1  # 4 natural periods per rise
    cyc = mechanics.residual_vibration(f, t, ecam.law("cycloidal"))
    har = mechanics.residual_vibration(f, t, ecam.law("harmonic"))
    assert cyc < har
    # a law is taken by name wherever laws are accepted; a dwell leaves nothing to ring
    assert mechanics.residual_vibration(f, t, "cycloidal") == cyc
    assert mechanics.residual_vibration(f, t, "dwell") == 0.0


@pytest.mark.parametrize("periods_per_rise", [0.5, 1.5, 4.5])
def test_residual_vibration_of_the_cycloid_is_its_closed_form(periods_per_rise):
    # Undamped follower, rise of time T, natural frequency f, lam = f T. The error e = x - y
    # obeys e'' + w^2 e = -y''; after the rise it rings with amplitude |int y'' e^{iw t} dt| / w.
    # For the cycloid, s'' = 2 pi sin(2 pi u), the integral is closed-form and, per unit
    # stroke, the amplitude is |sin(pi lam)| / (pi lam |1 - lam^2|).
    lam = periods_per_rise
    exact = abs(math.sin(math.pi * lam)) / (math.pi * lam * abs(1.0 - lam**2))
    rise_s = 0.1
    assert mechanics.residual_vibration(lam / rise_s, rise_s, "cycloidal") == \
        pytest.approx(exact, rel=1e-6)


@pytest.mark.parametrize("call", [
    lambda: mechanics.reflected_inertia(-1.0, 0.5),
    lambda: mechanics.reflected_inertia(1.0, 0.5, 1.5),
    lambda: mechanics.two_mass_frequency(0.0, 1, 1),
    lambda: mechanics.two_mass_frequency(float("nan"), 1, 1),
    lambda: mechanics.wind_up_angle("12", 1e4),
    lambda: mechanics.wind_up_angle(float("inf"), 1e4),
    lambda: mechanics.torsional_harmonic(100.0, 0.0),
    lambda: mechanics.torsional_harmonic(-1.0, 3.0),
    lambda: mechanics.resonance_excitation_check(100.0, 0.0, [0.0, 1.0], 5.0),
    lambda: mechanics.peak_torque_check([], 10.0),
    lambda: mechanics.peak_torque_check([[1.0, 2.0]], 10.0),
    lambda: mechanics.rms_torque_check(["a"], 10.0),
    lambda: mechanics.rms_torque_check([1.0], -1.0),
    lambda: mechanics.wind_up_check(0.05, stiffness=1e4, peak_torque=1.0, twist=[]),
    lambda: mechanics.wind_up_check(0.05, stiffness=0.0, peak_torque=1.0),
    lambda: mechanics.residual_vibration(40.0, 0.1, "cycloid"),
])
def test_bad_values(call):
    with pytest.raises(InputError, match=r"^\w+: .+ should be "):
        call()
