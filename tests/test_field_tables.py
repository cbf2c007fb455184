"""The field tables the reference pages are generated from (ecam.cam_fields,
hil_sim.scene_fields) agree with the parsers: every key a parser accepts has a row, no row names
a key the parser refuses, and every row's numeric limits are the ones the parser enforces (the
value at a limit accepted, a value just past it refused with a message naming the field)."""

from __future__ import annotations

import copy
import re

import pytest

from ecam.cam_fields import CAM_FIELDS, CAM_TABLES
from ecam.camfile import parse_cam
from ecam.errors import EcamError
from ecam.field_table import check_probe_values
from hil_sim.machine import parse_machine
from hil_sim.machine_fields import MACHINE_FIELDS, MACHINE_TABLES
from hil_sim.scene import parse_scene
from hil_sim.scene_fields import SCENE_FIELDS, SCENE_TABLES

UNKNOWN = "zz_not_a_field"

BASE_SCENE = {
    "master": {"speed": 360.0},
    "cam": {"file": "combination_drrd.toml"},  # a built-in cam, found by name
    "drive": {"gains": {}},
    "mechanics": {"motor_inertia": 1e-4, "load_inertia": 1e-3},
    "bus": {"faults": {}},
    "limits": {"tracking_error": 0.01},
    "duration": {"master_periods": 1.0},
    "event": [{"action": "offset", "at_s": 0.0}],
    "tappet": [{"on": 10.0, "off": 20.0}],
}
BASE_CAM = {
    "master_period": 360.0,
    "table": {},
    # strokes small enough that a start at the slave limit keeps every segment end inside it
    "segment": [{"law": "cycloidal", "span": 180.0, "stroke": 0.01},
                {"law": "cycloidal", "span": 180.0, "stroke": -0.01}],
    "tappet": [{"on": 10.0, "off": 20.0}],
}
# A machine of one axis: its master, bus and duration the machine's, the rest the axis's.
BASE_MACHINE = {
    "master": {"speed": 360.0},
    "bus": {"faults": {}},
    "limits": {"bus_load_percent": 80.0},
    "duration": {"master_periods": 1.0},
    "axis": [{"name": "a", "node_id": 1, "cam": {"file": "combination_drrd.toml"},
              "mechanics": {"motor_inertia": 1e-4, "load_inertia": 1e-3},
              "limits": {"tracking_error": 0.01}}],
}
# Settings a choice needs before it parses (the other choices' own fields).
CHOICE_CONTEXT = {
    ("master.profile", "start_stop"): {"master.max_acceleration": 1000.0, "master.max_jerk": 1e5},
    ("master.profile", "cam_in"): {"master.engage_at": 0.0, "master.max_velocity": 1.0,
                                   "master.slave_max_acceleration": 10.0,
                                   "master.slave_max_jerk": 1000.0},
    ("segment.law", "dwell"): {"segment.stroke": None},
    ("event.action", "switch"): {"event.cam": "combination_drrd.toml"},
    ("event.action", "phase"): {"event.shift": 1.0, "event.max_velocity": 1.0,
                                "event.max_acceleration": 1.0, "event.max_jerk": 1.0},
    ("event.action", "cam_out"): {"event.max_velocity": 1.0, "event.max_acceleration": 1.0,
                                  "event.max_jerk": 1.0},
    ("event.activation", "master_position"): {"event.activation_position": 0.0},
    ("event.start_mode", "ramp_in"): {"event.max_velocity": 1.0, "event.max_acceleration": 1.0,
                                      "event.max_jerk": 1.0},
}


def _scene(data):
    return parse_scene(data, source="probe.toml")


def _cam(data):
    return parse_cam(data, source="probe.toml")


def _machine(data):
    return parse_machine(data, source="probe.toml")


FORMATS = {
    "scene": (SCENE_FIELDS, SCENE_TABLES, BASE_SCENE, _scene),
    "cam": (CAM_FIELDS, CAM_TABLES, BASE_CAM, _cam),
    "machine": (MACHINE_FIELDS, MACHINE_TABLES, BASE_MACHINE, _machine),
}


def _table(data, dotted: str, create: bool = True) -> dict:
    """The mapping of a dotted table in ``data`` (``segment``: the first segment)."""
    node = data
    for part in filter(None, dotted.split(".")):
        if part in ("segment", "tappet", "event", "axis") and isinstance(node.get(part), list):
            node = node[part][0]
        else:
            node = node.setdefault(part, {}) if create else node[part]
    return node


def _set(data, dotted: str, value) -> None:
    table, _, key = dotted.rpartition(".")
    target = _table(data, table)
    if value is None:
        target.pop(key, None)
    else:
        target[key] = value


def _accepted_keys(parse, base, table: str) -> set[str]:
    """What the parser accepts in ``table``: the list its unknown-field message gives."""
    data = copy.deepcopy(base)
    _table(data, table)[UNKNOWN] = 1
    with pytest.raises(EcamError) as caught:
        parse(data)
    message = str(caught.value)
    found = re.search(r"unknown field; expected one of (.*)$", message)
    assert found, f"[{table}] unknown field not refused as such: {message}"
    return set(found.group(1).split(", "))


@pytest.mark.parametrize("kind", FORMATS)
def test_every_accepted_key_has_a_row_and_every_row_is_accepted(kind):
    fields, tables, base, parse = FORMATS[kind]
    parse(copy.deepcopy(base))  # the base is valid
    rows = {}
    for field in fields:
        assert field.table in tables, f"{field.name}: table [{field.table}] has no description"
        assert (field.table, field.key) not in rows, f"{field.name}: two rows"
        rows[(field.table, field.key)] = field
    for table in tables:
        accepted = _accepted_keys(parse, base, table)
        documented = {key for (t, key) in rows if t == table}
        assert not accepted - documented, (
            f"{kind} [{table}]: the parser accepts {sorted(accepted - documented)} without a row "
            f"in the field table (add them: ecam/cam_fields.py or hil_sim/scene_fields.py)")
        assert not documented - accepted, (
            f"{kind} [{table}]: rows for {sorted(documented - accepted)}, which the parser refuses")
        for key in accepted:
            if rows[(table, key)].kind.endswith("table") and table == "":
                # [sweep] is read by hil_sim.sweep_spec (ecam sweep), not by the scene's parser,
                # and its fields are documented in docs/sweep.md; a machine's [master], [bus]
                # and [duration] are a scene's (their rows are SCENE_FIELDS')
                assert key in tables or key in ("segment", "sweep") or (
                    kind == "machine" and key in SCENE_TABLES), f"[{key}] has no section"


def _probe_cases():
    for kind, (fields, _, _, _) in FORMATS.items():
        for field in fields:
            for value, ok in check_probe_values(field):
                yield pytest.param(kind, field, value, ok, id=f"{kind}:{field.name}={value!r}")


@pytest.mark.parametrize("kind, field, value, accepted", list(_probe_cases()))
def test_the_limits_are_the_parsers(kind, field, value, accepted):
    _, _, base, parse = FORMATS[kind]
    data = copy.deepcopy(base)
    for name, setting in field.when:
        _set(data, name, setting)
    _set(data, field.name, value)
    if field.name == "master_period":  # the segments cover the period
        for segment in data["segment"]:
            segment["span"] = value / 2
        for tappet in data.get("tappet", []):  # and the tappets lie within it
            tappet["on"], tappet["off"] = value / 36, value / 18
    if accepted:
        parse(data)
    else:
        with pytest.raises(EcamError) as caught:
            parse(data)
        assert field.key in str(caught.value), str(caught.value)


@pytest.mark.parametrize("kind", FORMATS)
def test_the_choices_are_the_parsers(kind):
    fields, _, base, parse = FORMATS[kind]
    for field in fields:
        if not field.choices or not field.probe:
            continue
        for choice in field.choices:
            data = copy.deepcopy(base)
            for name, setting in field.when:
                _set(data, name, setting)
            _set(data, field.name, choice)
            for name, setting in CHOICE_CONTEXT.get((field.name, choice), {}).items():
                _set(data, name, setting)
            if field.name == "segment.law" and choice in ("poly5", "poly7", "spline"):
                continue  # solved from boundary conditions: needs neighbours, tested in test_camfile;
                # a spline's knots replace the span: tested in test_fit
            parse(data)
        data = copy.deepcopy(base)
        _set(data, field.name, "not_a_choice")
        with pytest.raises(EcamError) as caught:
            parse(data)
        message = str(caught.value)
        for choice in field.choices:
            assert choice in message, f"{field.name}: {choice!r} not among {message}"
