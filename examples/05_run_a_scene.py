"""05: the lift scene on the rig, then the fastest master speed at which every check passes."""

from pathlib import Path

import hil_sim

HERE = Path(__file__).resolve().parent
scene = hil_sim.load_scene(HERE / "project" / "scenes" / "lift.toml")
report = hil_sim.run_scene(scene)
print("passed" if report.passed else "failed")
for check in report.checks:
    print(" ", check.line())
fastest = hil_sim.find_max_speed(scene)
print(f"max speed {fastest['speed']:.4g} {fastest['unit']} "
      f"({fastest['periods_per_minute']:.4g} cycles per minute)")
