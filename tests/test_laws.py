"""Motion laws: end values, derivative consistency, symmetry, and the published peak values."""
import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

import ecam
from ecam.laws import LAWS, polynomial_from_boundary

PI = math.pi
NAMES = sorted(LAWS)
# Published characteristic values (Cv, Ca, Cj), derived in closed form; None: unbounded.
PUBLISHED = {
    "cycloidal": (2.0, 2 * PI, 4 * PI**2),
    "harmonic": (PI / 2, PI**2 / 2, None),
    "poly345": (1.875, 10 / math.sqrt(3), 60.0),
    # modified sine: the fast quarter sine (4 pi per unit) starts the jerk at 4 pi * Ca
    "modified_sine": (4 * PI / (4 + PI), 4 * PI**2 / (4 + PI), 16 * PI**3 / (4 + PI)),
    "constant_velocity": (1.0, None, None),
    "constant_acceleration": (2.0, 4.0, None),
    "cubic": (1.5, 6.0, None),
    # 4-5-6-7: s' = 140 u^3 (1-u)^3 peaks at u = 1/2; with x = 1 - 2u, s'' = 26.25 x (1 - x^2)^2
    # peaks at x = 1/sqrt(5), so Ca = 16.8/sqrt(5); the jerk peaks at the middle, 52.5
    "poly4567": (140 / 64, 16.8 / math.sqrt(5), 52.5),
    # modified trapezoid: Ca = 1 / (1/4 + 1/(2 pi)) * 1/2 ... derived: A (1/4 + 1/(2 pi)) = Cv = 2
    "modified_trapezoid": (2.0, 2 / (0.25 + 1 / (2 * PI)), 4 * PI * 2 / (0.25 + 1 / (2 * PI))),
    # cycloidal ramps over a quarter: V = 4/3, A = 2 pi V, J = 4 pi A
    "modified_constant_velocity": (4 / 3, 8 * PI / 3, 32 * PI**2 / 3),
    "half_cycloid_start": (2.0, PI, PI**2),
    "half_harmonic_end": (PI / 2, PI**2 / 4, None),
}
SYMMETRIC = ["cycloidal", "harmonic", "poly345", "poly4567", "modified_sine", "modified_trapezoid",
             "modified_constant_velocity", "cubic", "constant_acceleration", "constant_velocity"]


@pytest.mark.parametrize("name", NAMES)
def test_end_values(name):
    law = ecam.law(name)
    assert law(0.0) == pytest.approx(0.0, abs=1e-14)
    assert law(1.0) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("name", NAMES)
@given(u=st.floats(0.01, 0.99))
def test_derivatives_agree_with_finite_differences(name, u):
    law = ecam.law(name)
    eps = 1e-6
    for order in range(3):
        # skip points straddling an inner break, where the next derivative may jump
        if any(abs(u - b) < 2 * eps for b in law.breaks):
            return
        numeric = (law(u + eps, order) - law(u - eps, order)) / (2 * eps)
        exact = law(u, order + 1)
        assert numeric == pytest.approx(exact, rel=1e-5, abs=1e-5 * max(1.0, abs(law(u, order)) / eps * 1e-6 + 1))


@pytest.mark.parametrize("name", SYMMETRIC)
@given(u=st.floats(0.0, 1.0))
def test_symmetric_laws(name, u):
    law = ecam.law(name)
    assert law(u) + law(1 - u) == pytest.approx(1.0, abs=1e-12)
    assert law(u, 1) == pytest.approx(law(1 - u, 1), abs=1e-9)


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_published_characteristic_values(name):
    law = ecam.law(name)
    for measured, published in zip((law.cv, law.ca, law.cj), PUBLISHED[name]):
        if published is None:
            assert measured == math.inf
        else:
            assert measured == pytest.approx(published, rel=1e-9)


@pytest.mark.parametrize("name", NAMES)
def test_peaks_match_dense_sampling(name):
    """The characteristic values are real peaks of the implemented law (not typed-in numbers)."""
    law = ecam.law(name)
    u = np.linspace(0, 1, 200001)
    for order, value in ((1, law.cv), (2, law.ca), (3, law.cj)):
        sampled = np.abs(law(u, order)).max()
        if math.isfinite(value):
            assert value >= sampled - 1e-9
            assert value == pytest.approx(sampled, rel=1e-6)


def test_unknown_law_names_the_choices():
    with pytest.raises(ecam.InputError, match="law: 'cycloid' should be one of constant_acceleration, constant_velocity, "):
        ecam.law("cycloid")


def test_half_curves_join_the_combination_seed():
    c1, h2 = ecam.law("half_cycloid_start"), ecam.law("half_harmonic_end")
    assert c1(1.0, 1) == pytest.approx(2.0)  # ends at peak velocity
    assert h2(0.0, 1) == pytest.approx(PI / 2)
    assert c1(0.0, 1) == 0 and c1(0.0, 2) == pytest.approx(0, abs=1e-15)
    assert h2(1.0, 1) == pytest.approx(0, abs=1e-15)


@given(
    v0=st.floats(-20, 20), a0=st.floats(-200, 200), v1=st.floats(-20, 20), a1=st.floats(-200, 200),
    j0=st.floats(-2000, 2000), j1=st.floats(-2000, 2000),
)
def test_boundary_polynomials_meet_their_conditions(v0, a0, v1, a1, j0, j1):
    p5 = polynomial_from_boundary((v0, a0), (v1, a1))
    p7 = polynomial_from_boundary((v0, a0, j0), (v1, a1, j1))
    for p, start, end in ((p5, (v0, a0), (v1, a1)), (p7, (v0, a0, j0), (v1, a1, j1))):
        assert p(0.0) == pytest.approx(0, abs=1e-9) and p(1.0) == pytest.approx(1, abs=1e-9)
        for order, (s, e) in enumerate(zip(start, end), start=1):
            assert p(0.0, order) == pytest.approx(s, abs=1e-7 * (1 + abs(s)))
            assert p(1.0, order) == pytest.approx(e, abs=1e-7 * (1 + abs(e)))


def test_rest_to_rest_polynomials_are_the_classical_laws():
    u = np.linspace(0, 1, 101)
    np.testing.assert_allclose(polynomial_from_boundary((0, 0), (0, 0))(u), LAWS["poly345"](u), atol=1e-12)
    np.testing.assert_allclose(polynomial_from_boundary((0, 0, 0), (0, 0, 0))(u), LAWS["poly4567"](u), atol=1e-12)


def test_bad_boundary_conditions():
    with pytest.raises(ecam.InputError, match=r"start: \(0.0,\) should be 2 values \(5th order\) or 3 values \(7th order\)"):
        polynomial_from_boundary((0,), (0,))
    with pytest.raises(ecam.InputError, match=r"start\[0\]: nan should be finite"):
        polynomial_from_boundary((math.nan, 0), (0, 0))
    with pytest.raises(ecam.InputError, match=r"end: \(0.0, 0.0, 0.0\) should be 2 values, as many as start"):
        polynomial_from_boundary((0, 0), (0, 0, 0))


def test_higher_orders_for_the_certificate():
    """Orders past jerk are exact too (the compiler's error bound uses the 4th and 6th)."""
    harmonic = ecam.law("harmonic")
    u = np.linspace(0, 1, 11)
    np.testing.assert_allclose(harmonic(u, 4), -(PI**4) / 2 * np.cos(PI * u), atol=1e-9)
    np.testing.assert_allclose(harmonic(u, 6), (PI**6) / 2 * np.cos(PI * u), atol=1e-7)


def test_characteristic_values_follow_the_law_not_its_address():
    # Temporaries freed one after another reuse addresses; a cache keyed by id() handed the
    # previous law's Cv to the next one (most of them before the fix).
    import gc

    from ecam.laws import _peak

    addresses, reused = set(), 0
    gc.freeze()  # the collections below then walk only the laws made here, not the whole heap
    try:
        for i in range(30):
            law_ = polynomial_from_boundary((0.01 * i + (i % 17) * 0.2, 0.0), (0.5, 0.0))
            reused += id(law_) in addresses
            addresses.add(id(law_))
            assert law_.cv == pytest.approx(_peak(law_, 1), rel=1e-12)
            del law_
            gc.collect()  # a law sits in a reference cycle: free it so its address is reused
    finally:
        gc.unfreeze()
    assert reused > 0  # the case above was really exercised
