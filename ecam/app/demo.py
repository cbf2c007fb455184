"""`ecam demo`, the main job on the built-in examples: the seed cams checked, plotted and compiled
into certified tables; then the seed cam on the rig, on a stiff coupling (passes) and on a soft one
at high master speed (fails, and the report says which check and by how much)."""

from __future__ import annotations

import time
from pathlib import Path

from ecam.atomic_files import write_files

from ecam.camfile import CAMS_DIR, load_cam
from ecam.compile import compile_table
from ecam.errors import InputError
from ecam.plot import plot_profile
from hil_sim import SCENES_DIR
from hil_sim.rig import run_scene
from hil_sim.scene import load_scene

from .cam_commands import certificate_text, print_check, write_table
from .html_report import html_report
from .progress import progress_bar

SEED_CAMS = ("combination_drrd", "modified_sine")
DEMO_SCENES = ("stiff_coupling", "soft_coupling")
# What the demo says before each scene: the soft coupling fails on purpose.
SCENE_INTRO = {
    "stiff_coupling": "a stiff coupling at 60 rpm: every check should pass",
    "soft_coupling": "a soft coupling at 150 rpm: this scene FAILS ON PURPOSE, to show what a failing "
                     "check looks like (which check, by how much, where in the cycle); it is not an "
                     "error of your install",
}


def run_demo(output) -> int:
    """Write the demo's plots and tables into ``output`` and print what they show.

    Writes ``<stem>.png`` and the tables for each seed cam, ``sim_<scene>.png`` for each rig
    scene and ``report.html``, one self-contained page of the rig results.

    Returns 0: a failing scene is an expected part of the demo, not an error of the run.
    """
    out = Path(output)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"output directory {str(out)!r} cannot be created: {exc.strerror or exc}") from None
    print("ecam demo: the seed cams, checked, plotted and compiled into certified tables\n")
    for stem in SEED_CAMS:
        profile = load_cam(CAMS_DIR / f"{stem}.toml")
        print_check(profile, profile.check())
        picture = out / f"{stem}.png"
        plot_profile(profile, picture)
        table = compile_table(profile, progress=progress_bar(f"certifying {stem}"))
        files = write_table(table, stem, out, ["c", "bin"])
        print(certificate_text(stem, table))
        print(f"  wrote {picture}, {', '.join(files)}\n")
    print("ecam demo: the seed cam on the software-in-the-loop rig (virtual CANopen, CiA 402 drive)\n")
    results = []
    for name in DEMO_SCENES:
        path = SCENES_DIR / f"{name}.toml"
        picture = out / f"sim_{name}.png"
        print(f"-- {name}: {SCENE_INTRO[name]}")
        start = time.perf_counter()
        report = run_scene(load_scene(path), plot=picture)
        results.append((path, report, time.perf_counter() - start))
        print(report.to_text().rstrip())
        print(f"  plots: {picture}\n")
    page = out / "report.html"
    write_files({page: html_report(results, title="ecam demo: the seed cam on the rig")})
    verdicts = ", ".join(f"{path.stem} {'passed' if report.passed else 'failed'}" for path, report, _ in results)
    print(f"ecam demo: done ({verdicts}, as intended: the soft coupling fails on purpose)")
    print(f"ecam demo: open {page} in a browser for the verdicts, checks, plots and scenes")
    return 0
