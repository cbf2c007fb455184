"""The effects that change a verdict: their values, the measured choice of a run's model, the
full model, and the bus-free path that measures them (bit-identical to the CANopen run)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ecam.errors import CamFileError
from hil_sim import SCENES_DIR
from hil_sim.effects import EFFECT_NAMES, resolve
from hil_sim.plant import ARCMIN
from hil_sim.rig import run_scene
from hil_sim.scene import DurationSpec, load_scene

SHIPPED = sorted(SCENES_DIR.glob("*.toml"))
PHYSICAL = ("following_error", "tracking_error", "coupling_peak_torque", "coupling_rms_torque",
            "wind_up", "motor_saturation", "faults")


def short(scene, cycles):
    return replace(scene, duration=DurationSpec(cycles=cycles))


# ---------------------------------------------------------------------------------- values

def test_defaults_scale_with_the_machine_and_the_scene_overrides_them():
    soft = load_scene(SCENES_DIR / "soft_coupling.toml")
    values = resolve(soft.mechanics.build(), {}, {}, soft.drive.control_rate_hz)
    assert values["gear_backlash"].value == pytest.approx(3 * ARCMIN)  # standard planetary
    assert values["motor_coulomb_friction"].value == pytest.approx(0.06)  # 1 % of 6 N m
    assert values["load_coulomb_friction"].value == pytest.approx(0.01 * 6.0 * 0.95 / 0.1)
    # a bellows of 60 N m rated: J = 5.4e-7 T^1.48 (RINGFEDER GWB fit)
    assert values["coupling_inertia"].value == pytest.approx(5.4e-7 * 60.0**1.48)
    assert values["encoder"].value == 2**20 and values["current_loop"].value == 1000.0
    assert values["computation_delay"].value == 1.0
    assert values.velocity_filter_hz == pytest.approx(0.25 * 4000.0)
    assert all(v.source.startswith("default: ") for v in values.values
               if v.name != "torsional_compliance")
    given = resolve(soft.mechanics.build(), {"gear_backlash": 0.0, "coupling_inertia": 1e-3},
                    {"encoder_counts_per_rev": 0, "computation_delay": False}, 4000.0)
    assert not given["gear_backlash"].applies and given["gear_backlash"].source == "scene"
    assert given["coupling_inertia"].value == 1e-3
    assert not given["encoder"].applies and not given["computation_delay"].applies
    # a rigid axis without a gear: no compliance, no backlash, no coupling inertia
    ballscrew = load_scene(SCENES_DIR / "drive_side.toml")
    rigid = resolve(ballscrew.mechanics.build(), {}, {}, 4000.0)
    assert rigid.applicable == ("motor_coulomb_friction", "load_coulomb_friction", "encoder",
                                "current_loop", "computation_delay")


def test_effect_fields_are_checked_where_they_enter(tmp_path):
    text = (SCENES_DIR / "stiff_coupling.toml").read_text()
    cam = (SCENES_DIR / "../../firmware_tables/cams/combination_drrd.toml").resolve()
    text = text.replace('"../../firmware_tables/cams/combination_drrd.toml"', repr(str(cam)))
    cases = {
        "gear_backlash = 0.0": ("gear_backlash = 4.0", "mechanics.gear_backlash: 4 should be <= 3.14"),
        "substeps = 4": ("substeps = 4\nencoder_counts_per_rev = 2", "drive.encoder_counts_per_rev: 2 should be 0"),
        'model = "auto"': ('model = "auto"\ncomputation_delay = 1', "drive.computation_delay: 1 should be"),
        'cam_mode = "controller"': ('cam_mode = "controller"\nfidelity = "most"', "fidelity: 'most' should be one of"),
        "wind_up_deg = 0.05": ("wind_up_deg = 0.05\ntracking_window = [1.0]", "limits.tracking_window: [1.0] should be [start, end]"),
    }
    for old, (new, message) in cases.items():
        assert old in text, old
        path = tmp_path / "bad.toml"
        path.write_text(text.replace(old, new))
        with pytest.raises(CamFileError) as error:
            load_scene(path)
        assert message in str(error.value), str(error.value)


# --------------------------------------------------------------------- the model a run picks

@pytest.mark.slow
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_the_default_model_gives_the_full_models_verdicts(path):
    """Every shipped scene: the default (measured) run and --fidelity full give the same verdict
    per check, and every check's value within 10 % of the full one (issue 10, item 3), the
    information lines' too; a check counted in whole numbers (counts, faults) may differ by
    its one step (1 count against 3 is the value's resolution, not the model's)."""
    scene = load_scene(path)
    auto = run_scene(scene, path="fast")
    full = run_scene(scene.with_fidelity("full"), path="fast")
    assert [c.passed for c in auto.checks] == [c.passed for c in full.checks], auto.to_text()
    for a, f in zip(auto.checks, full.checks):
        if a.value is None or f.value is None:
            assert a.value is f.value
            continue
        step = 1.0 if f.name in ("following_error", "faults") else 0.0
        assert abs(a.value - f.value) <= max(0.10 * abs(f.value), step), (
            path.stem, a.line(), f.line())
    proof = auto.summary["fidelity_proof"]
    assert proof["same_verdicts"] and proof["largest_difference"] <= 0.02
    assert proof["within_relative"] and proof["largest_relative"] <= 0.10
    listed = [e["name"] for e in auto.summary["effects"]]
    assert listed == list(EFFECT_NAMES)
    assert all(e["included"] for e in full.summary["effects"] if e["value"] != "n/a"
               and not e["value"].startswith("0 ") and e["value"] != "none")


def test_ideal_fidelity_models_no_effect_and_picks_the_model_by_rule():
    scene = short(load_scene(SCENES_DIR / "stiff_coupling.toml"), 300).with_fidelity("ideal")
    report = run_scene(scene, path="fast")
    assert report.summary["fidelity"] == "ideal"
    assert not any(e["included"] for e in report.summary["effects"])
    assert report.model == "rigid" and "2641 Hz" in report.model_reason
    # the rule weighs the controller's rate: the 2.6 kHz mode lies above its Nyquist frequency
    assert "above the controller's Nyquist frequency 2000 Hz" in report.model_reason
    # said once, as one sentence
    assert report.model_reason.count("rigid model") == 1 and not report.model_reason.endswith("..")


def test_a_scene_can_force_the_model():
    base = short(load_scene(SCENES_DIR / "stiff_coupling.toml"), 300)
    forced = replace(base, drive=replace(base.drive, model="rigid"))
    report = run_scene(forced, path="fast")
    compliance = next(e for e in report.summary["effects"] if e["name"] == "torsional_compliance")
    assert report.model == "rigid" and not compliance["included"]
    assert compliance["why"] == "drive.model = 'rigid'"


@pytest.mark.slow
def test_an_effect_left_unsaid_is_modelled_and_the_drive_is_tuned_for_it():
    """The stiff scene says its reducer has no backlash; with the 3 arcmin of a standard
    planetary gearhead the cam's torque reversals hammer the flanks through the stiff coupling:
    the coupling's peak torque grows more than tenfold. With the fixed 200 Hz gains of old the
    motor limit-cycled through the gap (4 x the coupling's maximum); commissioned with the gap
    in its loop (issue 20) the drive runs a lower bandwidth and the machine passes (the scene
    file's comment quotes this)."""
    base = load_scene(SCENES_DIR / "stiff_coupling.toml")
    effects = tuple((k, v) for k, v in base.mechanics.effects if k != "gear_backlash")
    with_backlash = replace(base, mechanics=replace(base.mechanics, effects=effects))
    report = run_scene(with_backlash, path="fast")
    backlash = next(e for e in report.summary["effects"] if e["name"] == "gear_backlash")
    assert backlash["included"] and backlash["source"].startswith("default: 3 arcmin")
    without = run_scene(base, path="fast")
    peak = report.check("coupling_peak_torque")
    assert peak.value > 10 * without.check("coupling_peak_torque").value
    assert report.summary["tuning"]["loops"]["backlash_gap"]["stable"]
    assert (report.summary["tuning"]["velocity_bandwidth_hz"]
            < 0.6 * without.summary["tuning"]["velocity_bandwidth_hz"])
    assert report.passed
    old = replace(with_backlash, drive=replace(with_backlash.drive, gains=(
        ("velocity_bandwidth_hz", 200.0),)))
    hammered = run_scene(old, path="fast")
    assert hammered.check("coupling_peak_torque").ratio > 3.0
    assert not hammered.check("loop_stability").passed


def test_the_report_lists_every_effect_in_and_out_and_why():
    report = run_scene(short(load_scene(SCENES_DIR / "soft_coupling.toml"), 400))
    text = report.to_text()
    assert "effects (fidelity auto, measured on" in text
    for name in EFFECT_NAMES:
        assert f"  {name}: " in text
    assert "  in   encoder: " in text or "  out  encoder: " in text
    # whose value each is: the scene's, or the rig's documented default
    assert "torsional_compliance: 3000 N m/rad (scene); " in text
    assert "gear_backlash: 0.0008727 rad (3 arcmin) (default); " in text
    assert report.to_dict()["effects"][0]["name"] == "torsional_compliance"


# ------------------------------------------------------------------------- bus-free path

@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_the_bus_free_path_is_bit_identical_to_the_canopen_run(path):
    scene = short(load_scene(path), 600)
    over_bus, bus_free = run_scene(scene), run_scene(scene, path="fast")
    assert over_bus.cycles == bus_free.cycles
    assert over_bus.summary["effects"] == bus_free.summary["effects"]
    for name in ("following_error", "tracking_error", "coupling_torque", "peak_coupling_torque",
                 "peak_motor_torque"):
        a, b = over_bus.series[name], bus_free.series[name]
        assert np.array_equal(a, b, equal_nan=True), name
    for a, b in zip(over_bus.checks, bus_free.checks):
        if a.name != "bus_load":
            assert (a.name, a.value, a.passed) == (b.name, b.value, b.passed)
    assert bus_free.check("bus_load").limit is None and "bus-free" in bus_free.check("bus_load").detail


def test_the_bus_free_path_stops_at_the_same_following_error_fault():
    base = load_scene(SCENES_DIR / "soft_coupling.toml")
    tight = replace(short(base, 2000), drive=replace(base.drive, following_error_window=40))
    over_bus, bus_free = run_scene(tight), run_scene(tight, path="fast")
    assert over_bus.cycles == bus_free.cycles < 2000
    assert over_bus.summary["faults"][0]["code"] == bus_free.summary["faults"][0]["code"] == "0x8611"


# ------------------------------------------------------------------------------ CSP timeline

def test_a_master_that_does_not_lead_makes_the_drive_lag_a_cycle():
    base = short(load_scene(SCENES_DIR / "drive_side.toml"), 1000)
    base = replace(base, cam_mode="controller")
    late = replace(base, master=replace(base.master, lead_cycles=0))
    on_time, lagging = run_scene(base, path="fast"), run_scene(late, path="fast")
    # one cycle of the slave's travel: up to (peak velocity x 1 ms)
    assert lagging.check("tracking_error").value > 2.0 * on_time.check("tracking_error").value


@pytest.mark.slow
def test_the_effects_are_measured_on_a_quick_run():
    """A long run at a constant master repeats its cam periods: the effects are measured on its
    first 3 periods at cruise (the stiff scene: 1 Hz cam, 1 kHz bus: 3000 cycles), not 13 times
    as long as the scene (issue 10, item 3: "a quick run with and without it")."""
    long = short(load_scene(SCENES_DIR / "stiff_coupling.toml"), 20_000)
    report = run_scene(long, path="fast")
    assert report.cycles == 20_000
    assert report.summary["fidelity_proof"]["cycles"] == 3000
    assert "bus-free runs of 3000 cycles" in report.to_text()
    quick = run_scene(short(load_scene(SCENES_DIR / "stiff_coupling.toml"), 3000), path="fast")
    assert report.summary["effects"] == quick.summary["effects"]
    # a master that stops again is measured over the whole run (its stop comes last)
    assert run_scene(short(load_scene(SCENES_DIR / "rotary_knife.toml"), 600), path="fast"
                     ).summary["fidelity_proof"]["cycles"] == 600
