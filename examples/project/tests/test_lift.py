"""The lift station's rig tests: run with `pytest examples/project` (the `run_scene` fixture
comes from ecam's pytest plugin, installed with ecam)."""

from pathlib import Path

from ecam.app.pytest_plugin import assert_check, assert_margin, assert_passes

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def test_lift_passes_at_60_cycles_per_minute(run_scene):
    report = run_scene(SCENES / "lift.toml", master_periods=1.0)
    assert_passes(report)                               # every check line printed; fails on any
    assert_margin(report, "tracking_error", share=0.5)  # keep half the tracking limit in reserve


def test_lift_is_not_torque_limited(run_scene):
    report = run_scene(SCENES / "lift.toml", master_periods=1.0)
    assert_check(report, "motor_saturation")
