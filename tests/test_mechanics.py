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


def test_coupling_checks():
    checks = mechanics.coupling_check(12.0, rated_torque=10.0, max_torque=20.0, stiffness=1e4,
                                      excitation_hz=50.0, inertia_1=1e-3, inertia_2=1e-3)
    by_name = {c["name"]: c for c in checks}
    assert not by_name["coupling_torque_rated"]["passed"] and by_name["coupling_torque_max"]["passed"]
    assert by_name["wind_up_angle"]["value"] == pytest.approx(12.0 / 1e4)


def test_residual_vibration_smaller_for_smoother_laws():
    import ecam

    f, t = 40.0, 0.1  # 4 natural periods per rise
    cyc = mechanics.residual_vibration(f, t, ecam.law("cycloidal"))
    har = mechanics.residual_vibration(f, t, ecam.law("harmonic"))
    assert cyc < har


@pytest.mark.parametrize("call", [
    lambda: mechanics.reflected_inertia(-1.0, 0.5),
    lambda: mechanics.reflected_inertia(1.0, 0.5, 1.5),
    lambda: mechanics.two_mass_frequency(0.0, 1, 1),
    lambda: mechanics.two_mass_frequency(float("nan"), 1, 1),
])
def test_bad_values(call):
    with pytest.raises(InputError):
        call()


def test_math_core_imports_no_can_and_no_plotting():
    """The math core stays pure: CAN and plotting come in only at the edges."""
    import subprocess
    import sys

    code = ("import sys, ecam, ecam.compile, ecam.export, ecam.app.firmware; "
            "print(sorted(m for m in ('can', 'canopen', 'matplotlib', 'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
