"""Machine files (TOML): several cam axes driven by one virtual master on one bus.

A machine is a list of axes; each axis is a :class:`~hil_sim.scene.Scene` of its own, read by
the scene's own section parsers (:func:`hil_sim.scene.parse_scene`) from the machine's shared
``[master]``, ``[bus]`` and ``[duration]`` and the axis's own tables. A scene file in today's
format (no ``[[axis]]``) is a machine of one (:func:`load_machine`).

Layout::

    name = "packaging_line"            # optional, default the file name
    description = "..."                # optional

    [master]                           # the virtual master (electronic line shaft): as a scene's
    speed_rpm = 60.0                   # profile "constant" or "start_stop" (a cam-in is per axis
                                       # and not offered for a machine)
    [bus]                              # one bus for all axes: bitrate and faults, as a scene's
    bitrate = 1000000

    [limits]                           # the machine's own checks
    bus_load_percent = 80.0            # optional, default 100

    [duration]                         # as a scene's; master_periods needs one master period
    master_periods = 4.0               # for all axes (else give cycles or seconds)

    [[axis]]
    name = "knife"                     # distinct
    node_id = 4                        # distinct CANopen node ids, 1..127
    cam_mode = "controller"            # or "drive"
    fidelity = "auto"
    phase = 90.0                       # master units added to the master's position (default 0)
    [axis.cam]                         # a scene's [cam], [drive] (without node_id; every axis
    [axis.drive]                       # at the same cycle_s: one SYNC), [mechanics], [motor]
    [axis.mechanics]                   # (sizing) and [limits]
    [axis.limits]
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

from ecam.camfile import read_toml
from ecam.validate import MAX_DESCRIPTION_CHARS, Fields, fail, show
from hil_sim.scene import MAX_MASTER_SPEED, Scene, parse_scene

#: The keys of one ``[[axis]]`` table.
AXIS_KEYS = ("name", "node_id", "cam_mode", "fidelity", "phase", "cam", "drive", "mechanics",
             "motor", "limits", "event", "tappet")
#: At most this many axes: the node ids of one CANopen network (CiA 301: 1..127).
MAX_AXES = 127


@dataclass(frozen=True)
class Machine:
    """A machine as read from a machine file (see the module docstring for the layout).

    Attributes
    ----------
    name : str
    path : Path or None
    axes : tuple of Scene
        One scene per axis, in the file's order; each has the machine's master, bus and
        duration, and its own name, node id, cam, phase, drive, mechanics, limits, fidelity.
    bus_load_percent : float
        The machine's bus load limit.
    description : str
    single : bool
        True when read from a scene file in today's format (a machine of one): its report is
        the scene's.
    """

    name: str
    path: Path | None
    axes: tuple
    bus_load_percent: float = 100.0
    description: str = ""
    single: bool = False

    @property
    def cycle_s(self) -> float:
        """The bus cycle (SYNC period) of every axis [s]."""
        return self.axes[0].drive.cycle_s

    @property
    def bus(self):
        """The machine's bus (:class:`hil_sim.scene.BusSpec`), shared by every axis."""
        return self.axes[0].bus

    def with_fidelity(self, fidelity: str) -> "Machine":
        """The same machine with every axis at another fidelity."""
        return replace(self, axes=tuple(a.with_fidelity(fidelity) for a in self.axes))


def is_machine_data(data) -> bool:
    """True when a parsed TOML mapping is a machine file (it has ``[[axis]]``)."""
    return isinstance(data, dict) and "axis" in data


def load_machine(path) -> Machine:
    """Read and validate a machine file, or a scene file as a machine of one.

    Raises
    ------
    CamFileError
        Missing or unreadable file, invalid TOML, or a bad field: one line naming the field
        (``axis[1].drive.cycle_s``, or the axis' scene field with the axis in the source), the
        value and what was expected.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise fail("path", path, "a machine or scene file path (str or Path)")
    path = Path(path)
    data = read_toml(path, "scene file")  # a machine file is a scene file of several axes
    if not is_machine_data(data):
        scene = parse_scene(data, base=path.parent, source=path.name, path=path.resolve())
        return Machine(name=scene.name, path=scene.path, axes=(scene,),
                       bus_load_percent=scene.limits.bus_load_percent,
                       description=scene.description, single=True)
    return parse_machine(data, base=path.parent, source=path.name, path=path.resolve())


def parse_machine(data: dict, base: Path = Path("."), source: str = "<machine>",
                  path: Path | None = None) -> Machine:
    """Build a :class:`Machine` from a parsed TOML mapping (as :func:`load_machine`)."""
    top = Fields(data, "", f"machine {source}", {"name", "description", "master", "bus",
                                                 "limits", "duration", "axis"})
    name = top.text("name", default=Path(source).stem)
    description = top.text("description", default="", maximum=MAX_DESCRIPTION_CHARS)
    limits = top.table("limits", {"bus_load_percent"})
    bus_load = limits.number("bus_load_percent", default=100.0, minimum=0.0, strict=True)
    master = top.table("master", None, required=True)
    if master.raw.get("profile") == "cam_in":
        raise master.error("master.profile: 'cam_in' should be 'constant' or 'start_stop' in a "
                           "machine (the virtual master runs all axes; a cam-in is one axis')")
    tables = data["axis"]
    if not isinstance(tables, list) or not tables or len(tables) > MAX_AXES:
        raise top.error(f"axis: {show(tables)} should be 1..{MAX_AXES} [[axis]] tables")
    axes = []
    for i, table in enumerate(tables):
        axes.append(_axis(top, i, table, base, source))
    _check_axes(top, axes)
    return Machine(name=name, path=path, axes=tuple(axes), bus_load_percent=bus_load,
                   description=description)


def _axis(top: Fields, i: int, table, base: Path, source: str) -> Scene:
    """Axis ``i``: its own tables with the machine's master, bus and duration, read by the
    scene parser (its messages name the axis in the source: ``scene x.toml axis[1] (knife)``)."""
    raw = Fields(table, f"axis[{i}]", top.source, AXIS_KEYS)
    name = raw.text("name", required=True)
    node_id = raw.integer("node_id", required=True, minimum=1, maximum=127)
    phase = raw.number("phase", default=0.0, minimum=-MAX_MASTER_SPEED, maximum=MAX_MASTER_SPEED)
    drive = raw.table("drive", None)
    if "node_id" in drive:
        raise drive.error(f"{drive.name('node_id')}: give the node id as axis[{i}].node_id")
    mapping = {key: table[key] for key in ("cam_mode", "fidelity", "cam", "mechanics", "motor",
                                           "limits", "event", "tappet") if key in table}
    mapping.update({"name": name, "drive": {**drive.raw, "node_id": node_id}})
    for key in ("master", "bus", "duration"):
        if key in top.raw:
            mapping[key] = top.raw[key]
    scene = parse_scene(mapping, base=base, source=f"{source} axis[{i}] ({name})")
    return replace(scene, phase=float(phase))


def _check_axes(top: Fields, axes: list) -> None:
    """The rules between axes: distinct names and node ids, one SYNC period."""
    first = axes[0]
    names, nodes = {}, {}
    for i, axis in enumerate(axes):
        if axis.name in names:
            raise top.error(f"axis[{i}].name: {show(axis.name)} should be distinct (axis"
                            f"[{names[axis.name]}] has it)")
        names[axis.name] = i
        node = axis.drive.node_id
        if node in nodes:
            raise top.error(f"axis[{i}].node_id: {node} should be distinct (axis[{nodes[node]}] "
                            "has it: one CANopen network)")
        nodes[node] = i
        if not math.isclose(axis.drive.cycle_s, first.drive.cycle_s, rel_tol=0.0, abs_tol=0.0):
            raise top.error(f"axis[{i}].drive.cycle_s: {show(axis.drive.cycle_s)} should be "
                            f"{show(first.drive.cycle_s)} (axis[0]'s: one SYNC period for the "
                            "machine)")
