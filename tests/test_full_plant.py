"""The full plant: gear backlash, Coulomb friction and coupling inertia on the two-mass model."""

import math

import numpy as np
import pytest

from ecam.errors import InputError
from hil_sim.plant import ARCMIN, FullPlant
from hil_sim.plant import MechanicalEffects as Effects
from ecam.mechanics import Mechanics
from hil_sim.plant import Plant, TwoMassPlant

DT = 1e-3 / 16


def axis(**overrides):
    values = dict(motor_inertia=2e-4, gear_ratio=0.1, load_inertia=0.05, coupling_stiffness=2e4,
                  coupling_damping=2.0, motor_damping=1e-4, load_damping=0.01, gear_efficiency=0.95)
    values.update(overrides)
    return Mechanics(**values)


def test_without_effects_it_is_the_two_mass_plant():
    m = axis()
    full, linear = FullPlant(m, Effects(), DT), TwoMassPlant(m, DT)
    full.reset(0.3, 5.0)
    linear.reset(0.3, 5.0)
    rng = np.random.default_rng(7)
    for torque in rng.normal(0.0, 2.0, 2000):
        full.step(torque)
        linear.step(torque)
    np.testing.assert_allclose(full.x, linear.x, rtol=1e-9, atol=1e-12)
    assert full.coupling_torque == pytest.approx(linear.coupling_torque, rel=1e-8, abs=1e-9)


def test_motor_friction_stops_a_coasting_axis_when_the_energy_says_and_holds_it_at_rest():
    # Stiff coupling, no viscous terms: the axis decelerates at F / J_eq and stops at J_eq w0 / F.
    m = axis(coupling_stiffness=1e7, coupling_damping=50.0, motor_damping=0.0, load_damping=0.0,
             gear_efficiency=1.0)
    friction = 0.2
    plant = FullPlant(m, Effects(motor_coulomb_friction=friction), DT)
    w0 = 100.0
    plant.reset(0.0, w0)
    j_eq = m.motor_inertia + m.load_inertia * m.gear_ratio**2
    expected = j_eq * w0 / friction
    steps = 0
    while plant.motor_speed > 0.0 and steps < 10**6:
        plant.step(0.0)
        steps += 1
    assert steps * DT == pytest.approx(expected, rel=0.01)
    for _ in range(200):  # stiction: no creep, no chatter
        plant.step(0.0)
        assert plant.motor_speed == 0.0


def test_a_torque_below_the_friction_does_not_move_the_axis():
    m = axis()
    plant = FullPlant(m, Effects(motor_coulomb_friction=0.5, load_coulomb_friction=2.0), DT)
    plant.reset(1.0, 0.0)
    for _ in range(500):
        plant.step(0.3)
    assert plant.motor_speed == 0.0 and plant.load_speed == 0.0
    assert plant.motor_angle == pytest.approx(1.0, abs=1e-15)


def test_the_load_stays_put_until_the_gear_takes_up_the_backlash():
    backlash = 3 * ARCMIN
    m = axis()
    plant = FullPlant(m, Effects(gear_backlash=backlash), DT)
    plant.reset()
    crossed = None
    for k in range(4000):
        plant.step(0.05)
        if crossed is None and abs(plant.twist) <= backlash / 2:
            assert plant.load_speed == 0.0 and plant.coupling_torque == 0.0
        elif crossed is None:
            crossed = k
    assert crossed is not None and crossed > 0
    assert plant.load_speed > 0.0 and plant.coupling_torque > 0.0
    # Inside the gap the motor turns alone: r * (T t^2 / 2 J_m) = backlash / 2.
    expected = math.sqrt(backlash * m.motor_inertia / (m.gear_ratio * 0.05))
    assert abs((crossed + 1) * DT - expected) <= 1.5 * DT


def test_coupling_inertia_splits_half_to_each_side():
    m = axis(coupling_stiffness=1e8, coupling_damping=200.0, motor_damping=0.0, load_damping=0.0,
             gear_efficiency=1.0)
    extra = 0.01
    with_coupling = FullPlant(m, Effects(coupling_inertia=extra), DT)
    for plant in (with_coupling,):
        plant.reset()
        for _ in range(1600):
            plant.step(1.0)
    j_eq = m.motor_inertia + (m.load_inertia + extra) * m.gear_ratio**2
    assert with_coupling.motor_speed == pytest.approx(1600 * DT / j_eq, rel=2e-3)


def test_the_effects_dissipate_energy():
    m = axis()
    plant = FullPlant(m, Effects(gear_backlash=8 * ARCMIN, motor_coulomb_friction=0.01,
                                 load_coulomb_friction=0.5, coupling_inertia=1e-3), DT)
    plant.reset(0.0, 50.0)

    def energy():
        e = plant.effects
        jm = m.motor_inertia + 0.5 * e.coupling_inertia * m.gear_ratio**2 / m.gear_efficiency
        jl = m.load_inertia + 0.5 * e.coupling_inertia
        return 0.5 * (jm * plant.motor_speed**2 + (jl * plant.load_speed**2
                                                   + m.coupling_stiffness * plant.wind_up**2) / m.gear_efficiency)

    before = energy()
    history = []
    for _ in range(40000):
        plant.step(0.0)
        history.append(energy())
    assert max(history) <= before * (1 + 1e-9)
    assert history[-1] < 1e-3 * before


@pytest.mark.parametrize("field,value,message", [
    ("gear_backlash", -1e-3, "gear_backlash: -0.001 should be >= 0"),
    ("load_coulomb_friction", math.inf, "load_coulomb_friction: inf should be finite"),
    ("gear_backlash", 4.0, "gear_backlash: 4 should be <= pi rad (half a turn)"),
])
def test_bad_effects_are_one_line(field, value, message):
    with pytest.raises(InputError) as info:
        Effects(**{field: value})
    assert str(info.value) == message


def _friction_by_loop(free, motor, load, speeds, limits, iterations):
    """The friction solve as the plant wrote it as a loop over lists (the oracle of the compiled
    one): projected Gauss-Seidel on w_end = free + G f, each torque clipped to its limit."""
    limit_m, limit_l = limits
    i_m, i_l = speeds
    g11, g12, g21, g22 = motor[i_m], load[i_m], motor[i_l], load[i_l]
    v_m, v_l = free[i_m], free[i_l]
    f_m = f_l = 0.0
    for _ in range(iterations if limit_m and limit_l else 1):
        previous_m, previous_l = f_m, f_l
        if limit_m:
            f_m = min(max(-(v_m + g12 * f_l) / g11, -limit_m), limit_m)
        if limit_l:
            f_l = min(max(-(v_l + g21 * f_m) / g22, -limit_l), limit_l)
        if f_m == previous_m and f_l == previous_l:
            break
    if f_l:
        out = [v + a * f_m + b * f_l for v, a, b in zip(free, motor, load)]
    else:
        out = [v + a * f_m for v, a in zip(free, motor)]
    if limit_m and -limit_m < f_m < limit_m:
        out[i_m] = 0.0
    if limit_l and -limit_l < f_l < limit_l:
        out[i_l] = 0.0
    return out, f_m, f_l


def test_the_compiled_friction_solve_is_the_loop_float_for_float():
    """hil_sim.discretize.friction_step (straight-line code with the constants in) gives the
    loop's floats exactly: one friction or two, sliding or held, rigid (one shaft) or two-mass."""
    from hil_sim.discretize import friction_step

    rng = np.random.default_rng(20261125)
    cases = 0
    for n, speeds in ((2, (1, 1)), (3, (1, 1)), (4, (1, 3)), (5, (1, 3))):
        for _ in range(60):
            motor = list(rng.normal(size=n) * 10.0 ** rng.integers(-6, 2))
            load = list(rng.normal(size=n) * 10.0 ** rng.integers(-6, 2))
            motor[speeds[0]] = abs(motor[speeds[0]]) + 1e-6  # a torque speeds its own shaft up
            load[speeds[1]] = abs(load[speeds[1]]) + 1e-6
            limits = [float(rng.choice([0.0, rng.uniform(0.01, 2.0)])) for _ in range(2)]
            if n < 4:
                limits[1] = 0.0  # one shaft: both frictions act on it as one
            if not any(limits):
                continue
            correct = friction_step(motor, load, speeds, limits, 12)
            for _ in range(20):
                free = list(rng.normal(size=n) * 10.0 ** rng.integers(-8, 1))
                assert correct(free) == _friction_by_loop(free, motor, load, speeds, limits, 12)
                cases += 1
    assert cases > 2000


# ------------------------------------------------------------------ friction in sub-steps

def stiff_axis(**overrides):
    """A coupling mode of about 2.6 kHz (stiff_coupling's): 11 sub-steps of a 250 us step."""
    values = dict(motor_inertia=1.2e-4, gear_ratio=0.1, load_inertia=0.02,
                  coupling_stiffness=2e6, coupling_damping=5.0, motor_damping=1e-4,
                  load_damping=0.02, gear_efficiency=0.95)
    values.update(overrides)
    return Mechanics(**values)


FRICTIONS = [Effects(motor_coulomb_friction=0.06, load_coulomb_friction=0.57),
             Effects(motor_coulomb_friction=0.06, load_coulomb_friction=0.57,
                     coupling_inertia=2.3e-4),
             Effects(load_coulomb_friction=0.3), Effects(motor_coulomb_friction=0.1)]


@pytest.mark.parametrize("effects", FRICTIONS)
@pytest.mark.parametrize("lag", [None, 1000.0])
def test_a_whole_step_is_the_sub_steps_where_it_is_taken(effects, lag):
    """Where the plant takes a step whole (both frictional shafts sliding throughout, or both
    held throughout), it lands where its own sub-steps land: sliding to rounding, held to the
    drift the sub-steps' own solve leaves (a current loop's torque moving inside a sub-step
    moves the shafts inside it), which shrinks with them."""
    rng = np.random.default_rng(2611)
    plant = Plant(stiff_axis(), 250e-6, effects=effects, current_loop_hz=lag)
    assert plant._inner == 11 and plant._slide is not None
    fine = Plant(stiff_axis(), 250e-6, effects=effects, current_loop_hz=lag, substeps=11)
    finer = Plant(stiff_axis(), 250e-6, effects=effects, current_loop_hz=lag, substeps=176)
    assert fine._slide is None
    taken = {"sliding": 0, "held": 0, "sub-stepped": 0}
    limits = effects.motor_coulomb_friction, effects.load_coulomb_friction
    for _ in range(800):
        held = rng.random() < 0.4
        speed = 0.0 if held else rng.normal(0.0, 1.0) * 10.0 ** rng.integers(-3, 2)
        relative = 0.0 if held else rng.normal(0.0, 1e-2) * 10.0 ** rng.integers(-3, 1)
        twist = rng.normal(0.0, 0.8 * max(limits) / 2e6)
        x = [rng.normal(0.0, 100.0), speed, twist, 0.1 * speed - relative]
        if lag:
            x.append(rng.normal(0.0, 0.1))
        torque = rng.normal(0.0, 0.1)
        slid = plant._slide(list(x), torque)
        fine._x = list(x)
        fine.step(torque)
        if slid is None:
            taken["sub-stepped"] += 1
            continue
        state, f_m, f_l = slid
        if x[1] == 0.0 and x[3] == 0.0:
            taken["held"] += 1
            assert state[1] == 0.0 and state[3] == 0.0 and state[0] == x[0]
            assert fine.motor_speed == 0.0 and fine.load_speed == 0.0
            finer._x = list(x)
            finer.step(torque)
            drift, finer_drift = abs(fine.twist - x[2]), abs(finer.twist - x[2])
            assert abs(state[2] - finer.twist) <= 2.0 * finer_drift + 1e-18
            assert finer_drift <= drift / 8 + 1e-18
        else:
            taken["sliding"] += 1
            assert (f_m, f_l) == fine.friction_torques
            np.testing.assert_allclose(state[1:], fine.x[1:], rtol=1e-9, atol=1e-13)
    both = all(limits)  # held whole needs both shafts held by friction
    assert taken["sliding"] >= 30 and taken["sub-stepped"] >= 30, taken
    assert taken["held"] >= 30 if both else taken["held"] == 0, taken


@pytest.mark.parametrize("effects", FRICTIONS[:2])
def test_advance_is_step_and_its_readings(effects):
    """The direct advance (whole steps and sub-steps) gives step()'s floats."""
    rng = np.random.default_rng(5)
    direct = Plant(stiff_axis(), 250e-6, effects=effects, current_loop_hz=1200.0)
    stepped = Plant(stiff_axis(), 250e-6, effects=effects, current_loop_hz=1200.0)
    for plant in (direct, stepped):
        plant.reset(0.2, 3.0)
    torques = np.concatenate([rng.normal(0.0, 0.5, 400), np.zeros(400), rng.normal(0, 0.02, 400)])
    for torque in torques:
        angle, speed, coupling, wind = direct.advance(torque)
        stepped.step(torque)
        assert direct._x == stepped._x
        assert (angle, speed, coupling, wind) == (stepped.motor_angle, stepped.motor_speed,
                                                  stepped.coupling_torque, stepped.wind_up)
        assert direct.friction_torques == stepped.friction_torques


def test_substeps_are_checked_and_leave_a_linear_plant_whole():
    with pytest.raises(InputError, match="substeps: 0 should be"):
        Plant(stiff_axis(), 250e-6, effects=FRICTIONS[0], substeps=0)
    assert Plant(stiff_axis(), 250e-6, substeps=64)._inner == 1
    assert Plant(stiff_axis(), 250e-6, effects=FRICTIONS[0], substeps=64)._inner == 64


@pytest.mark.slow
def test_stiff_coupling_friction_converges_to_the_64x_sub_stepped_plant(monkeypatch):
    """Issue 20, item 6: stiff_coupling at full fidelity, bus-free, its plant (2.6 kHz mode,
    250 us controller step) against the same plant sub-stepped 64x on every step: coupling peak
    and RMS within 1 %. Friction held for a whole controller step (1 sub-step: the former rig)
    puts the RMS more than 10 % high: the test fails without sub-steps."""
    import hil_sim.control as control
    from hil_sim import SCENES_DIR
    from hil_sim.rig import run as rig
    from hil_sim.rig.analysis import analyse
    from hil_sim.rig.fast import run_fast
    from hil_sim.scene import load_scene

    scene = load_scene(SCENES_DIR / "stiff_coupling.toml").with_fidelity("full")
    run, _ = rig.prepare(scene)
    setup = rig.axis_setup(run, run.effect_values.applicable)
    build = control.AxisSetup.build

    def coupling(substeps):
        def rebuilt(self, cycle_s, counts):
            axis = build(self, cycle_s, counts)
            if substeps is not None:
                p = axis.plant
                axis.plant = Plant(p.mechanics, p.dt, model=p.model, effects=p.effects,
                                   current_loop_hz=p.current_loop_hz, substeps=substeps)
                axis._place(counts)
            return axis
        monkeypatch.setattr(control.AxisSetup, "build", rebuilt)
        checks = {c.name: c.value for c in analyse(run, run_fast(run, setup)).checks}
        return np.array([checks["coupling_peak_torque"], checks["coupling_rms_torque"]])

    assert setup.build(1e-3, 0).plant._inner == 11  # ceil(250 us x 2641 Hz x 16)
    reference, default, held = coupling(64), coupling(None), coupling(1)
    np.testing.assert_allclose(default, reference, rtol=0.01)
    # with the auto-tuned drive (issue 20) the held friction puts the RMS 10 % high (the peak
    # 1 %); the old fixed gains put the peak more than 10 % high too
    assert held[1] > 1.1 * reference[1]
