"""Every field of a machine file (TOML) that a scene file does not have, as
:func:`hil_sim.machine.parse_machine` reads it (see :mod:`ecam.field_table`;
``tests/test_field_tables.py`` holds it to the parser). The machine's ``[master]``, ``[bus]`` and
``[duration]`` and each axis's ``[axis.cam]``, ``[axis.drive]`` (without ``node_id``),
``[axis.mechanics]``, ``[axis.motor]`` and ``[axis.limits]`` are a scene's tables, read by the
scene's parser: their rows are :data:`hil_sim.scene_fields.SCENE_FIELDS`.
"""

from __future__ import annotations

from ecam.field_table import REQUIRED, Field
from hil_sim.effects import FIDELITIES
from hil_sim.scene import CAM_MODES, MAX_MASTER_SPEED

__all__ = ["MACHINE_FIELDS", "MACHINE_TABLES"]

_PARSER = "hil_sim.machine"
_SCENE = "a scene's, every axis's (hil_sim.scene_fields)"

#: The tables of a machine file and what each holds, in the reference's order.
MACHINE_TABLES = {
    "": "The machine: several cam axes (stations) from one virtual master on one bus.",
    "limits": "The machine's own checks.",
    "axis": "One station (`[[axis]]`, in the order of the report): its own drive, cam and "
            "mechanics.",
}

MACHINE_FIELDS: tuple[Field, ...] = (
    Field("", "name", "string", "The machine's name in reports.",
          default_text="the file name without .toml", source=_PARSER),
    Field("", "description", "string", "Free text, shown in the HTML report.", default="",
          source=_PARSER),
    Field("", "master", "table", "The virtual master: a scene's `[master]` (constant or "
          "start_stop; speed_rpm is machine cycles per minute, every axis one cam period per "
          "machine cycle).", default=REQUIRED, source=_SCENE),
    Field("", "bus", "table", "The one bus of every axis: a scene's `[bus]`.",
          default_text="a scene's defaults", source=_SCENE),
    Field("", "limits", "table", "The `[limits]` table of the machine's own checks.",
          default_text="the defaults below"),
    Field("", "duration", "table", "How long to run, a scene's `[duration]`; master_periods "
          "needs one cycle count for every axis.", default=REQUIRED, source=_SCENE),
    Field("", "axis", "array", "The stations, `[[axis]]` tables.", default=REQUIRED,
          limits="1..127 tables: the node ids of one CANopen network", source=_PARSER),

    Field("limits", "bus_load_percent", "number", "The machine's bus_load check: the busiest "
          "SYNC period's bits (every node's frames) against this share of the period; the bus "
          "sizing uses it too.", unit="%", default=100.0, minimum=0.0, exclusive_minimum=True,
          source=_PARSER),

    Field("axis", "name", "string", "The station's name in reports (`<axis>.<check>`).",
          default=REQUIRED, limits="distinct", source=_PARSER),
    Field("axis", "node_id", "integer", "The station's drive's CANopen node id.",
          default=REQUIRED, minimum=1, maximum=127, limits="distinct (one network)",
          source="CiA 301: node ids 1..127"),
    Field("axis", "cam_mode", "choice", "Where the station's cam runs (a scene's cam_mode).",
          default="controller", choices=CAM_MODES, source=_SCENE),
    Field("axis", "fidelity", "choice", "Which effects the station's run models (a scene's "
          "fidelity).", default="auto", choices=FIDELITIES, source=_SCENE),
    Field("axis", "phase", "number", "The station's offset against the virtual master: added "
          "to the master position its cam sees.", unit="master units", default=0.0,
          minimum=-MAX_MASTER_SPEED, maximum=MAX_MASTER_SPEED, source=_PARSER),
    Field("axis", "cam", "table", "A scene's `[cam]`.", default=REQUIRED, source=_SCENE),
    Field("axis", "drive", "table", "A scene's `[drive]` without node_id.",
          default_text="a scene's defaults", limits="cycle_s the same on every axis (one SYNC)",
          source=_SCENE),
    Field("axis", "mechanics", "table", "A scene's `[mechanics]`.", default=REQUIRED,
          source=_SCENE),
    Field("axis", "motor", "table", "A scene's `[motor]` (sizing).", default_text="no motor",
          source=_SCENE),
    Field("axis", "limits", "table", "A scene's `[limits]`.", default=REQUIRED, source=_SCENE),
    Field("axis", "event", "array of tables", "A scene's `[[event]]`s: the station's cam switches, "
          "offsets, phase shifts and cam-out (hil_sim.events).", default_text="none", source=_SCENE),
    Field("axis", "tappet", "array of tables", "A scene's `[[tappet]]`s: the station's digital cam "
          "switches, their edges checked.", default_text="none", source=_SCENE),
)
