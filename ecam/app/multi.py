"""Run several scenes in one call: serial or in parallel processes, one progress line each.

    results = run_scenes(["hil_sim/scenes"], jobs=2, progress=print)
    print(summary_table(results))
    sys.exit(exit_status(results))

A path may be a scene file or a directory. In a directory every ``*.toml`` file that is a
scene (see :func:`is_scene_file`) is run, in sorted order; its other TOML files (cam files) are
skipped. Every scene is loaded and validated before the first one runs, so a bad field stops
the call at once with one line (:class:`~ecam.errors.CamFileError`) instead of after minutes of
simulation.

Results come back in the order of the inputs, whatever the number of processes: each is
``(scene, outcome, seconds)`` where ``scene`` is the scene file's path (or the
:class:`~hil_sim.scene.Scene` given), ``outcome`` is the :class:`~hil_sim.report.Report` or,
when the rig could not run the scene, the :class:`~ecam.errors.EcamError` it raised, and
``seconds`` the wall time of that run. The rig is deterministic and has no shared state
between runs, so ``jobs=N`` gives the same reports as a serial run (the tests compare their
JSON).
"""

from __future__ import annotations

import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from ecam.errors import CamFileError, EcamError, InputError

__all__ = ["SCENE_SECTIONS", "is_scene_file", "scene_files", "run_scenes", "summary_table",
           "exit_status", "outcome_line"]

#: Top-level keys only a scene file has; a cam file has none of them (it has [table] and
#: [[segment]]), so a directory may hold both.
SCENE_SECTIONS = ("cam_mode", "master", "cam", "drive", "mechanics", "bus", "limits", "duration")


def is_scene_file(path) -> bool:
    """True when ``path`` is a TOML file with at least one scene section.

    A file that is not valid TOML counts as a scene (it cannot be told apart from a broken
    one, and a broken scene must fail loudly, not vanish from a CI run).
    """
    from ecam.camfile import read_toml

    path = Path(path)
    if path.suffix != ".toml" or not path.is_file():
        return False
    try:
        data = read_toml(path, "scene file")
    except CamFileError:
        return True
    return any(key in data for key in SCENE_SECTIONS)


def scene_files(paths) -> list[Path]:
    """The scene files named by ``paths`` (files, or directories searched recursively).

    Raises
    ------
    InputError
        A path that does not exist, or a directory without any scene file.
    """
    found: list[Path] = []
    for item in paths:
        path = Path(item)
        if path.is_dir():
            inside = [p for p in sorted(path.rglob("*.toml")) if is_scene_file(p)]
            if not inside:
                raise InputError(f"scene directory {str(path)!r} holds no scene file (*.toml "
                                 f"with a [{'], ['.join(SCENE_SECTIONS[1:])}] table)")
            found.extend(inside)
        elif path.exists():
            found.append(path)
        else:
            raise InputError(f"scene {str(path)!r} does not exist")
    return found


def _load(items) -> list[tuple[object, object]]:
    """[(what the caller named, Scene)] for files, directories and Scene objects."""
    from hil_sim.scene import Scene, load_scene

    loaded = []
    for item in items:
        if isinstance(item, Scene):
            loaded.append((item, item))
        else:
            for path in scene_files([item]):
                loaded.append((path, load_scene(path)))
    return loaded


def _run_one(scene) -> tuple[object, float]:
    """Run one scene (in this process or a worker); return (Report or EcamError, seconds)."""
    from hil_sim.rig import run_scene

    start = time.perf_counter()
    try:
        outcome = run_scene(scene)
    except EcamError as exc:  # a scene the rig cannot run: reported, the others still run
        outcome = exc
    return outcome, time.perf_counter() - start


def run_scenes(paths, jobs: int = 1, progress=None) -> list[tuple[object, object, float]]:
    """Run scenes and return their results in the order given.

    Parameters
    ----------
    paths : iterable of str, Path or hil_sim.scene.Scene
        Scene files, directories of scene files, or scenes already loaded.
    jobs : int
        Number of worker processes; 1 runs in this process.
    progress : callable, optional
        Called with one line of text per finished scene (in the order they finish).

    Returns
    -------
    list of (scene, outcome, seconds)
        ``scene`` is the path (or the Scene given), ``outcome`` a Report, or the EcamError
        raised by a scene the rig could not run; ``seconds`` its wall time.

    Raises
    ------
    InputError
        ``jobs`` below 1, a missing path, or a scene file with a bad field (nothing is run).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"jobs: {jobs!r} should be an integer >= 1")
    loaded = _load(paths)
    results: list = [None] * len(loaded)
    total = len(loaded)
    done = 0

    def finished(index: int, outcome, seconds: float) -> None:
        nonlocal done
        done += 1
        named = loaded[index][0]
        results[index] = (named, outcome, seconds)
        if progress is not None:
            progress(f"[{done}/{total}] {outcome_line(_label(named), outcome, seconds)}")

    if jobs == 1 or total <= 1:
        for index, (_, scene) in enumerate(loaded):
            finished(index, *_run_one(scene))
        return results
    # spawn, not fork: the parent may hold CAN notifier threads and matplotlib state that a
    # forked child must not inherit; a fresh interpreter per worker costs about a second.
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(jobs, total), mp_context=context) as pool:
        futures = {pool.submit(_run_one, scene): index for index, (_, scene) in enumerate(loaded)}
        for future in as_completed(futures):
            finished(futures[future], *future.result())
    return results


def _label(scene) -> str:
    """A short name for a scene: its file name, or its name when given as a Scene."""
    if isinstance(scene, (str, Path)):
        return Path(scene).name
    return getattr(scene, "name", str(scene))


def outcome_line(label: str, outcome, seconds: float) -> str:
    """``stiff_coupling.toml: PASSED, 9 checks, 2000 cycles, 0.13 s`` or the failed checks."""
    if isinstance(outcome, BaseException):
        return f"{label}: ERROR {outcome} ({seconds:.2f} s)"
    if outcome.passed:
        return (f"{label}: PASSED, {len(outcome.checks)} checks, {outcome.cycles} cycles, "
                f"{seconds:.2f} s")
    failed = ", ".join(_failure(c) for c in outcome.failed)
    return f"{label}: FAILED {failed}; {outcome.cycles} cycles, {seconds:.2f} s"


def _failure(check) -> str:
    """``tracking_error x3.21`` (value over limit), or the name alone when not a ratio."""
    return f"{check.name} x{check.ratio:.3g}" if check.ratio is not None else check.name


def _worst(report):
    """The limited check closest to (or furthest past) its limit, or None."""
    rated = [c for c in report.checks if c.ratio is not None]
    failed = report.failed
    if failed:
        return failed[0] if not rated else max(failed, key=lambda c: c.ratio or float("inf"))
    return max(rated, key=lambda c: c.ratio) if rated else None


def summary_table(results) -> str:
    """A fixed-width table: one row per scene (verdict, model, cycles, worst check, wall time)
    and a last line ``N of M scenes passed``."""
    header = ("scene", "verdict", "model", "cycles", "worst check (value/limit)", "wall")
    rows = []
    for scene, outcome, seconds in results:
        if isinstance(outcome, BaseException):
            rows.append((_label(scene), "ERROR", "-", "-", str(outcome), f"{seconds:.2f} s"))
            continue
        worst = _worst(outcome)
        if worst is None:
            text = "-"
        else:
            text = f"{worst.name} {100.0 * worst.ratio:.3g} %" if worst.ratio is not None \
                else f"{worst.name} {worst.value}"
        rows.append((_label(scene), "PASS" if outcome.passed else "FAIL", outcome.model,
                     str(outcome.cycles), text, f"{seconds:.2f} s"))
    widths = [max(len(row[i]) for row in rows + [header]) for i in range(len(header))]
    right = {3, 5}

    def line(row) -> str:
        cells = [cell.rjust(w) if i in right else cell.ljust(w)
                 for i, (cell, w) in enumerate(zip(row, widths))]
        return "  ".join(cells).rstrip()

    passed = sum(1 for _, outcome, _ in results
                 if not isinstance(outcome, BaseException) and outcome.passed)
    lines = [line(header), line(tuple("-" * w for w in widths))] + [line(r) for r in rows]
    lines.append(f"{passed} of {len(results)} scenes passed")
    return "\n".join(lines) + "\n"


def exit_status(results) -> int:
    """0 when every scene ran and passed, else 1 (bad input is 2, raised before any run)."""
    ok = results and all(not isinstance(outcome, BaseException) and outcome.passed
                         for _, outcome, _ in results)
    return 0 if ok else 1
