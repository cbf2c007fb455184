"""Scenes from Python: load_scene(path, cam=profile) runs an in-memory cam instead of the file."""

import tomllib

import pytest

import ecam
from ecam import CamProfile, Segment
from ecam.errors import CamFileError, InputError
from hil_sim import SCENES_DIR
from hil_sim.scene import load_scene, parse_scene

STIFF = SCENES_DIR / "stiff_coupling.toml"


def knife():
    return CamProfile.from_segments([
        Segment.from_span(90.0), Segment.from_span(90.0, 0.5, "modified_sine", "rise"),
        Segment.from_span(90.0), Segment.from_span(90.0, -0.5, "cycloidal", "return"),
    ], name="python_cam", slave_unit="in")


def test_an_in_memory_cam_replaces_the_scenes_file_and_keeps_its_table_settings():
    from_file = load_scene(STIFF)
    scene = load_scene(STIFF, cam=knife())
    assert scene.cam.file is None
    assert scene.cam.load_profile().name == "python_cam"
    assert from_file.cam.load_profile().name != "python_cam"
    for setting in ("interp", "points", "tolerance", "master_counts", "slave_counts_per_unit"):
        assert getattr(scene.cam, setting) == getattr(from_file.cam, setting)


def _without_cam_file():
    data = tomllib.loads(STIFF.read_text())
    del data["cam"]["file"]
    return data


def test_with_an_in_memory_cam_the_scene_needs_no_cam_file():
    data = _without_cam_file()
    scene = parse_scene(data, cam=knife())
    assert scene.cam.load_profile().segments == knife().segments


def test_without_cam_file_or_in_memory_cam_the_error_names_cam_file():
    data = _without_cam_file()
    with pytest.raises(CamFileError) as info:
        parse_scene(data, source="x.toml")
    assert "cam.file" in str(info.value) and len(str(info.value).splitlines()) == 1


def test_a_cam_that_is_not_a_profile_is_one_line():
    with pytest.raises(InputError) as info:
        load_scene(STIFF, cam="knife.toml")
    assert str(info.value) == "cam: 'knife.toml' should be an ecam.CamProfile"


def test_the_in_memory_cam_round_trips_through_a_cam_file(tmp_path):
    cam = knife()
    path = tmp_path / "knife.toml"
    path.write_text(cam.to_toml())
    assert ecam.load_cam(path).segments == cam.segments


@pytest.mark.parametrize("table,values,message", [
    # Faults and Mechanics check their own values; the scene names them as the file does.
    ("bus", {"faults": {"drop": [{"cycle": -1, "frame": "sync"}]}},
     "bus.faults.drop[0].cycle: -1 should be an integer >= 0"),
    ("bus", {"faults": {"kinds": ["sync", "nmt"]}},
     "bus.faults.kinds[1]: 'nmt' should be one of sync, rpdo, tpdo"),
    ("bus", {"faults": {"sync_jitter_s": 1.0}}, "bus.faults.sync_jitter_s: 1 should be <= 0.1"),
    ("mechanics", {"coupling_rated_torque": 2.0, "coupling_max_torque": 1.0},
     "mechanics.coupling_max_torque: 1 should be >= coupling_rated_torque 2"),
    ("drive", {"model": "springy"},
     "drive.model: 'springy' should be one of auto, rigid, two_mass"),
])
def test_scene_errors_name_the_files_field(table, values, message):
    data = tomllib.loads(STIFF.read_text())
    data.setdefault(table, {}).update(values)
    with pytest.raises(CamFileError) as info:
        parse_scene(data, source="x.toml", cam=knife())
    assert str(info.value) == f"scene x.toml: {message}"
