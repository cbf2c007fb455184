"""hil_sim: the software-in-the-loop rig -- a virtual CANopen CiA 402 servo with motor, gear,
coupling and load, driven by a master-axis loop over python-can's virtual bus.

``hil_sim.VirtualDrive``, ``hil_sim.run_scene`` and ``hil_sim.load_scene`` are imported on first
use, so importing the package (as every ``ecam`` command does) does not load the CAN stack.
"""

from pathlib import Path

# The shipped example scenes (the demo's and the bench's).
SCENES_DIR = Path(__file__).resolve().parent / "scenes"

_LAZY = {
    "VirtualDrive": ("hil_sim.drive", "VirtualDrive"),
    "run_scene": ("hil_sim.rig", "run_scene"),
    "find_max_speed": ("hil_sim.rig", "find_max_speed"),
    "load_scene": ("hil_sim.scene", "load_scene"),
}
__all__ = ["SCENES_DIR", *sorted(_LAZY)]


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'hil_sim' has no attribute {name!r}")
    import importlib

    module, attribute = _LAZY[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value
