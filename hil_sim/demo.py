"""The rig half of ``ecam demo``: the seed cam on a stiff coupling (passes) and on a soft one at
high master speed (fails, and the report says which check and by how much)."""

from __future__ import annotations

from pathlib import Path

SCENES_DIR = Path(__file__).resolve().parent / "scenes"
DEMO_SCENES = ("stiff_coupling", "soft_coupling")


def run(output: Path) -> int:
    """Run the demo scenes, print their reports and write their plots into ``output``.

    Returns 0: a failing scene is an expected part of the demo, not an error of the run.
    """
    from .rig import run_scene
    from .scene import load_scene

    print("ecam demo: the seed cam on the software-in-the-loop rig (virtual CANopen, CiA 402 drive)\n")
    for name in DEMO_SCENES:
        scene = load_scene(SCENES_DIR / f"{name}.toml")
        picture = Path(output) / f"sim_{name}.png"
        report = run_scene(scene, plot=picture)
        print(report.to_text().rstrip())
        print(f"  plots: {picture}\n")
    return 0
