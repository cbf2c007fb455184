"""Run several scenes in one call: serial or in parallel processes, one progress line each.

    results = run_scenes(["hil_sim/scenes"], jobs=2, progress=print)
    print(summary_table(results))
    sys.exit(exit_status(results))

A path may be a scene file or a directory. In a directory every ``*.toml`` file that is a
scene (see :func:`is_scene_file`) is run, in sorted order; its other TOML files (cam files) are
skipped. A machine file (several ``[[axis]]``, :mod:`hil_sim.machine`) is one run too, its
outcome a :class:`~hil_sim.machine_report.MachineReport`. A path that does not exist, or a directory without a scene, stops the call at once
(a mistake on the command line; nothing runs).

A scene that cannot run does not stop the others, as one broken test does not stop a test
run: a file with a bad field (:class:`~ecam.errors.CamFileError`, found when it is loaded),
a run the rig cannot do (:class:`~ecam.errors.SimulationError`), or an unexpected exception
inside the rig (recorded as :class:`SceneCrashed` with its traceback) is that scene's outcome;
the JUnit XML shows it as an ``error`` testcase and the HTML report as an ERROR entry, and
the exit status is 2.

Results come back in the order of the inputs, whatever the number of processes: each is
``(scene, outcome, seconds)`` where ``scene`` is the scene file's path (or the
:class:`~hil_sim.scene.Scene` given), ``outcome`` is the :class:`~hil_sim.report.Report` or
the :class:`~ecam.errors.EcamError` that kept the scene from running, and ``seconds`` the wall
time of that run. The rig is deterministic and has no shared state between runs, so
``jobs=N`` gives the same reports as a serial run (the tests compare their JSON).
"""

from __future__ import annotations

import multiprocessing
import os
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from ecam.errors import CamFileError, EcamError, InputError, SimulationError
from ecam.validate import show_path

__all__ = ["SCENE_SECTIONS", "SceneCrashed", "is_scene_file", "scene_files", "run_scenes",
           "summary_table", "exit_status", "outcome_line", "scene_labels"]


class SceneCrashed(SimulationError):
    """An unexpected exception inside the rig while it ran one scene (a defect, not a bad
    scene): its type and message, and the traceback as text in :attr:`details`."""

    def __init__(self, message: str, details: str = "") -> None:
        super().__init__(message)
        self.details = details

    def __reduce__(self):  # picklable across worker processes, details included
        return (type(self), (str(self), self.details))

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
        if not str(item):  # Path("") is ".": every scene under the working directory
            raise InputError("scene '': should be a path (an empty argument names no file)")
        path = Path(item)
        if os.path.isdir(path):  # os.path never raises (Path.is_dir does past NAME_MAX)
            inside = [p for p in sorted(path.rglob("*.toml")) if is_scene_file(p)]
            if not inside:
                raise InputError(f"scene directory {show_path(path)} holds no scene file (*.toml "
                                 f"with a [{'], ['.join(SCENE_SECTIONS[1:])}] table)")
            found.extend(inside)
        elif os.path.lexists(path):
            found.append(path)
        else:
            raise InputError(f"scene {show_path(path)} does not exist")
    return found


def _load(items, fidelity: str | None = None) -> list[tuple[object, object]]:
    """[(what the caller named, Scene or the EcamError loading it raised)] for files,
    directories and Scene objects, each with ``fidelity`` when given. A missing path or an
    empty directory raises at once."""
    from hil_sim.machine import load_machine
    from hil_sim.scene import Scene

    loaded = []
    for item in items:
        if isinstance(item, Scene):
            loaded.append((item, item if fidelity is None else item.with_fidelity(fidelity)))
            continue
        for path in scene_files([item]):
            try:
                machine = load_machine(path)  # a scene file is a machine of one
                scene = machine.axes[0] if machine.single else machine
            except EcamError as exc:  # a broken scene file: reported, the others still run
                loaded.append((path, exc))
                continue
            loaded.append((path, scene if fidelity is None else scene.with_fidelity(fidelity)))
    return loaded


def _run_one(scene) -> tuple[object, float]:
    """Run one scene or machine (in this process or a worker); return (Report, MachineReport or
    EcamError, seconds)."""
    from hil_sim.machine import Machine
    from hil_sim.rig import run_scene
    from hil_sim.rig.machine_run import run_machine

    start = time.perf_counter()
    try:
        outcome = run_machine(scene) if isinstance(scene, Machine) else run_scene(scene)
    except EcamError as exc:  # a scene the rig cannot run: reported, the others still run
        outcome = exc
    except Exception as exc:  # a defect in the rig: this scene errors, the batch goes on
        outcome = SceneCrashed(f"the rig crashed: {type(exc).__name__}: {exc}",
                               traceback.format_exc())
    return outcome, time.perf_counter() - start


def run_scenes(paths, jobs: int = 1, progress=None,
               fidelity: str | None = None) -> list[tuple[object, object, float]]:
    """Run scenes and return their results in the order given.

    Parameters
    ----------
    paths : iterable of str, Path or hil_sim.scene.Scene
        Scene files, directories of scene files, or scenes already loaded.
    jobs : int
        Number of worker processes; 1 runs in this process.
    progress : callable, optional
        Called with one line of text per finished scene (in the order they finish).
    fidelity : {"auto", "full", "ideal"}, optional
        Run every scene with this fidelity instead of its own (``ecam sim --fidelity``).

    Returns
    -------
    list of (scene, outcome, seconds)
        ``scene`` is the path (or the Scene given), ``outcome`` a Report, or the EcamError
        that kept the scene from running (a bad field in its file, a run the rig cannot do,
        :class:`SceneCrashed`); ``seconds`` its wall time (0 for a file that did not load).

    Raises
    ------
    InputError
        ``jobs`` below 1, a path that does not exist, a directory without a scene file or
        an unknown ``fidelity`` (nothing is run).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"jobs: {jobs!r} should be an integer >= 1")
    loaded = _load(paths, fidelity)
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

    runnable = [(index, scene) for index, (_, scene) in enumerate(loaded)
                if not isinstance(scene, BaseException)]
    for index, (_, scene) in enumerate(loaded):
        if isinstance(scene, BaseException):
            finished(index, scene, 0.0)
    if jobs == 1 or len(runnable) <= 1:
        for index, scene in runnable:
            finished(index, *_run_one(scene))
        return results
    # spawn, not fork: the parent may hold CAN notifier threads and matplotlib state that a
    # forked child must not inherit; a fresh interpreter per worker costs about a second.
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(jobs, len(runnable)), mp_context=context) as pool:
        futures = {pool.submit(_run_one, scene): index for index, scene in runnable}
        for future in as_completed(futures):
            try:
                outcome, seconds = future.result()
            except BrokenProcessPool as exc:  # a worker killed (out of memory, a signal)
                outcome, seconds = SceneCrashed(f"its worker process died: {exc}"), 0.0
            except Exception as exc:  # the result could not come back (pickling)
                outcome, seconds = SceneCrashed(
                    f"its worker failed: {type(exc).__name__}: {exc}",
                    "".join(traceback.format_exception(exc))), 0.0
            finished(futures[future], outcome, seconds)
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
    """The check nearest its limit (largest value / limit), or None when none has a ratio."""
    rated = [c for c in report.checks if c.ratio is not None]
    return max(rated, key=lambda c: c.ratio) if rated else None


def summary_table(results) -> str:
    """A fixed-width table, one row per scene (its label from :func:`scene_labels`, verdict,
    model, cycles, wall time, and the failed checks with value / limit, or the check nearest
    its limit, or why the scene could not run), and a last line ``N of M scenes passed`` (with
    the count of scenes that could not run, if any)."""
    header = ("scene", "verdict", "model", "cycles", "wall",
              "failed checks (value / limit), or the check nearest its limit")
    rows = []
    labels = scene_labels([scene for scene, _, _ in results])
    for label, (scene, outcome, seconds) in zip(labels, results):
        if isinstance(outcome, BaseException):
            rows.append((label, "ERROR", "-", "-", f"{seconds:.2f} s", str(outcome)))
            continue
        if outcome.failed:
            text = ", ".join(_failure(c) for c in outcome.failed)
        else:
            worst = _worst(outcome)
            # the share of its limit the check uses (not its margin, which the text report gives)
            text = "-" if worst is None else f"{worst.name} at {100.0 * worst.ratio:.3g} % of its limit"
        rows.append((label, "PASS" if outcome.passed else "FAIL", outcome.model,
                     str(outcome.cycles), f"{seconds:.2f} s", text))
    widths = [max(len(row[i]) for row in rows + [header]) for i in range(len(header))]
    right = {3, 4}

    def line(row) -> str:
        cells = [cell.rjust(w) if i in right else cell.ljust(w)
                 for i, (cell, w) in enumerate(zip(row, widths))]
        return "  ".join(cells).rstrip()

    passed = sum(1 for _, outcome, _ in results
                 if not isinstance(outcome, BaseException) and outcome.passed)
    errors = sum(1 for _, outcome, _ in results if isinstance(outcome, BaseException))
    lines = [line(header), line(tuple("-" * w for w in widths))] + [line(r) for r in rows]
    lines.append(f"{passed} of {len(results)} scenes passed"
                 + (f", {errors} could not run" if errors else ""))
    return "\n".join(lines) + "\n"


def exit_status(results) -> int:
    """The status a batch exits with: the worst of what each scene would give alone.

    0 when every scene ran and passed; 1 when a check failed; 2 when a scene could not run
    (a bad scene file, as ``ecam sim`` gives for one bad file, or a rig error), whatever the
    others did. An empty batch is 2 (nothing was tested).
    """
    if not results or any(isinstance(outcome, BaseException) for _, outcome, _ in results):
        return 2
    return 0 if all(outcome.passed for _, outcome, _ in results) else 1


def scene_labels(scenes) -> list[str]:
    """A distinct name for each scene: its file stem, or, where two files share a stem
    (``line_a/knife.toml`` and ``line_b/knife.toml``), as many parent directories as it takes
    to tell them apart (``line_a/knife``). A Scene object is named by its ``name``.

    CI servers key test results by suite and case names (GitLab keeps only the first of two
    equal names), so the JUnit suites and the HTML sections use these.
    """
    paths = [Path(s) if isinstance(s, (str, Path)) else None for s in scenes]
    labels = []
    for scene, path in zip(scenes, paths):
        if path is None:
            labels.append(str(getattr(scene, "name", scene)))
            continue
        parts = path.with_suffix("").parts
        for depth in range(1, len(parts) + 1):
            label = "/".join(parts[-depth:])
            clash = [p for p in paths if p is not None and p != path
                     and "/".join(p.with_suffix("").parts[-depth:]) == label]
            if not clash:
                break
        labels.append(label)
    # Equal names left (the same file twice, or Scene objects with one name): number them.
    counts = {label: labels.count(label) for label in labels}
    seen: dict[str, int] = {}
    for i, label in enumerate(labels):
        if counts[label] > 1:
            seen[label] = seen.get(label, 0) + 1
            labels[i] = f"{label} ({seen[label]})"
    return labels
