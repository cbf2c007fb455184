"""hil_sim: the software-in-the-loop rig -- a virtual CANopen CiA 402 servo with motor, gear,
coupling and load, driven by a master-axis loop over python-can's virtual bus.

The rig in four calls (see the documentation's "Python API" page)::

    scene = hil_sim.load_scene(hil_sim.SCENES_DIR / "stiff_coupling.toml", cam=profile)
    report = hil_sim.run_scene(scene)          # a Report: passed, checks, summary, series
    print(report.to_text())
    fastest = hil_sim.find_max_speed(scene)    # a dict: speed, unit, failing_speed, ...

* ``SCENES_DIR``: the shipped example scenes (the demo's and the bench's);
* :func:`load_scene` / :func:`parse_scene`: a scene file (or its parsed TOML) -> :class:`Scene`,
  with an in-memory :class:`ecam.CamProfile` in place of the scene's cam file if given;
* :func:`run_scene` -> :class:`Report` (its :class:`Check` items each carry a value and a limit);
  :func:`find_max_speed`: the highest master speed at which every check passes;
* :class:`VirtualDrive`: the CiA 402 drive alone, for a CANopen master of your own;
* ``MACHINES_DIR``, :func:`load_machine`, :func:`run_machine` -> :class:`MachineReport`
  (several axes from one virtual master on one bus) and :func:`find_machine_max_speed` (the
  machine's speed, and the station and check that limit it).

Everything but ``SCENES_DIR`` is imported on first use, so ``import hil_sim`` (as every ``ecam``
command does) loads no CAN stack; running one does; reading a scene does not.
"""

from pathlib import Path

#: The shipped example scenes (the demo's and the bench's).
SCENES_DIR = Path(__file__).resolve().parent / "scenes"
#: The shipped machines (several axes on one bus; docs/machine.md).
MACHINES_DIR = Path(__file__).resolve().parent / "machines"

_LAZY = {
    "VirtualDrive": ("hil_sim.drive", "VirtualDrive"),
    "run_scene": ("hil_sim.rig", "run_scene"),
    "find_max_speed": ("hil_sim.rig", "find_max_speed"),
    "load_scene": ("hil_sim.scene", "load_scene"),
    "parse_scene": ("hil_sim.scene", "parse_scene"),
    "Scene": ("hil_sim.scene", "Scene"),
    "Report": ("hil_sim.report", "Report"),
    "Check": ("hil_sim.report", "Check"),
    "load_machine": ("hil_sim.machine", "load_machine"),
    "Machine": ("hil_sim.machine", "Machine"),
    "run_machine": ("hil_sim.rig.machine_run", "run_machine"),
    "find_machine_max_speed": ("hil_sim.rig.machine_search", "find_machine_max_speed"),
    "MachineReport": ("hil_sim.machine_report", "MachineReport"),
}
__all__ = ["MACHINES_DIR", "SCENES_DIR", *sorted(_LAZY)]


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'hil_sim' has no attribute {name!r}")
    import importlib

    module, attribute = _LAZY[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__():
    # The lazy names too: dir(hil_sim) and tab completion show the rig's API, not only Path.
    return sorted({*globals(), *_LAZY})
