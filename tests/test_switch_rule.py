"""One rule for a switch's coordinates everywhere (issue 23): `ecam check A --then B --at X`
(ecam.cam_join), the rig's `[[event]]` switches (hil_sim.events: switch_jumps) and the firmware's
queued switch (ecam.table_pair.SwitchPair, bit for bit with ecam_switch_pair) make the same join
for a pair of cams with net strokes, in all four PLCopen placements. With the master absolute the
new cam is evaluated at the absolute master position, with the net strokes of the periods before
(PLCopen MasterAbsolute; FORMAT.md step 7)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from ecam import compile_table, load_cam
from ecam.cam_join import join_cams
from ecam.table_pair import SwitchPair
from hil_sim import SCENES_DIR
from hil_sim.rig.cam import compile_cam
from hil_sim.rig.plan import count_cycles, plan_run
from hil_sim.scene import parse_scene

ROOT = Path(__file__).resolve().parents[1]
KNIFE = ROOT / "firmware_tables" / "cams" / "rotary_knife.toml"
PLACEMENTS = [(m, s) for m in ("absolute", "relative") for s in ("absolute", "relative")]
TURNS = 3  # the switch at the end of the knife's third period: master 1080 deg


@pytest.fixture(scope="module")
def twin(tmp_path_factory) -> Path:
    """A drum with two blades: half a turn per cut (net stroke 180 deg, 0.6 deg/deg in the cut),
    the knife's cam file with its strokes halved."""
    text = KNIFE.read_text()
    for old, new in (('name = "rotary_knife"', 'name = "twin_blade"'), ("net_stroke = 360.0", "net_stroke = 180.0"),
                     ("stroke = 36.0", "stroke = 18.0"), ("stroke = 288.0", "stroke = 144.0")):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path_factory.mktemp("cams") / "twin_blade.toml"
    path.write_text(text)
    assert load_cam(path).net_stroke == 180.0
    return path


def _rig_switch(twin: Path, master: str, slave: str):
    """The knife scene at constant speed for four periods, switched to the twin blade at the end of
    its third period (requested at 1000 deg, activated at the period end): the plan's switch."""
    data = tomllib.loads((SCENES_DIR / "rotary_knife.toml").read_text())
    data["master"] = {"speed_rpm": 120.0, "profile": "constant"}
    data["duration"] = {"master_periods": TURNS + 0.5}
    data["event"] = [{"action": "switch", "at_position": 1000.0, "cam": str(twin), "master": master,
                      "slave": slave, "allow_jump": True}]
    scene = parse_scene(data, base=SCENES_DIR, source="knife.toml")
    cam = compile_cam(scene)
    cycles = count_cycles(scene, cam.profile.master_period, scene.master.units_per_second(360.0))
    (switch,) = plan_run(scene, cam, np.zeros(cycles), cycles).events.switches
    return switch


@pytest.mark.parametrize("master, slave", PLACEMENTS)
def test_check_then_makes_the_rigs_join(twin, master, slave):
    """The rig's switch (left and right limits, the jumps of switch_jumps) is ecam check's join
    at the same master position, 1080 deg: with the master absolute the twin blade is entered
    with three of its net strokes (540 deg), not at its first period."""
    knife, blade = load_cam(KNIFE), load_cam(twin)
    join = join_cams(knife, blade, master=master, slave=slave, at=TURNS * 360.0)
    switch = _rig_switch(twin, master, slave)
    assert switch.master == pytest.approx(join.master, abs=1e-9) and switch.entry == pytest.approx(join.entry, abs=1e-9)
    assert switch.left == pytest.approx(join.left, rel=1e-12, abs=1e-9)
    assert switch.right == pytest.approx(join.right, rel=1e-12, abs=1e-9)
    assert {order: size for order, size in switch.jumps} == pytest.approx(
        {d.order: d.jump for d in join.report.discontinuities}, rel=1e-9, abs=1e-9)
    # the positions from the cams' definitions: the knife at 1080 deg stands at 3 x 360 deg
    expected = {("absolute", "absolute"): 3 * 180.0 - 3 * 360.0, ("absolute", "relative"): 3 * 180.0,
                ("relative", "absolute"): -3 * 360.0, ("relative", "relative"): 0.0}[master, slave]
    assert join.right[0] - join.left[0] == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("master, slave", PLACEMENTS)
def test_check_then_makes_the_firmwares_join(twin, master, slave):
    """SwitchPair (the C ecam_switch_pair's rules) switches at the boundary count 3 x 36000: its
    position there minus the knife's own is ecam check's position jump, in counts (1000 per deg),
    to the count (the tables are exact at their points, the boundary among them)."""
    knife, blade = load_cam(KNIFE), load_cam(twin)
    options = dict(interp="quintic", points=121, master_counts=36000, slave_counts_per_unit=1000, certify=False)
    running, pending = compile_table(knife, **options), compile_table(blade, **options)
    boundary = TURNS * running.master_counts
    pair = SwitchPair()
    pair.engage(running)
    pair.step(boundary - 10)
    pair.arm(pending, master=master, slave=slave)
    sample = pair.step(boundary)
    assert sample.switched
    join = join_cams(knife, blade, master=master, slave=slave, at=TURNS * 360.0)
    jump_counts = sample.position - int(running.lookup(boundary))
    assert jump_counts == round((join.right[0] - join.left[0]) * 1000)
