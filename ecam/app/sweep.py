"""Robustness sweeps over manufacturing spread, on Dask: many samples of one scene.

    summary = run_sweep("knife.toml", workers=2, directory="knife-sweep")
    print(format_summary(summary))

A sweep (the scene's ``[sweep]`` table, :mod:`hil_sim.sweep_spec`) draws a design
(:func:`ecam.sampling.design`) over the varied fields, builds each sample as the scene with
those values (every field validated again), and runs every sample at every judged speed on the
rig's bus-free path (:func:`ecam.app.sweep_sample.run_sample`), on ``dask.distributed``: a
``LocalCluster`` started and stopped here by default, or the cluster of a running scheduler.
Results come back as they finish and are appended to ``results.jsonl`` in the output directory
(one JSON object a line: a header naming the sweep, then one line per sample and speed), so an
interrupted sweep resumes with ``resume=True``; then the summary (:func:`summarize`) is computed
from the results sorted by sample and speed, so it is the same whatever the number of workers
and the order they finished in. The worst sample is run again over CANopen and its full report
kept (``worst_sample.json``).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ecam.atomic_files import write_files
from ecam.camfile import read_toml
from ecam.errors import EcamError, InputError, SimulationError
from ecam.sampling import Design, design
from ecam.statistics import max_speed_at_yield, proportion, rank_sensitivity, sobol_sensitivity
from ecam.validate import integer
from hil_sim.scene import Scene, parse_scene
from hil_sim.sweep_spec import SweepSpec, nominal_value, parse_sweep, sample_data

from .sweep_sample import run_sample

RESULTS_FILE = "results.jsonl"
SUMMARY_FILE = "summary.json"
WORST_FILE = "worst_sample.json"
#: The gains a nominal tuning pins in every sample's [drive.gains].
PINNED_GAINS = ("position_kp", "velocity_kp", "velocity_ki", "notch_hz")
#: Most runs (samples x judged speeds) one sweep may ask for.
MAX_RUNS = 1_000_000
INSTALL_HINT = "ecam sweep needs dask.distributed: pip install 'ecam[sweep]'"


@dataclass(frozen=True)
class SweepPlan:
    """Everything a sweep runs, known before the first sample: the scene (its mapping and the
    parsed nominal scene), the ``[sweep]`` table, the design, the judged speeds and the tasks."""

    path: Path
    data: dict
    scene: Scene
    spec: SweepSpec
    design: Design
    speeds: tuple[float, ...]
    unit: str
    nominal: dict
    gains: dict | None

    @property
    def fingerprint(self) -> str:
        """A hash of what decides the results: the scene mapping, the design's values, the
        speeds and the pinned gains (a results file from another sweep is refused)."""
        text = json.dumps({"data": self.data, "values": self.design.values.tolist(),
                           "speeds": list(self.speeds), "gains": self.gains}, sort_keys=True,
                          default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def task(self, index: int, speed_index: int) -> dict:
        """The worker's input for one sample at one speed."""
        data = sample_data(self.data, self.design.sample(index))
        if self.gains:
            drive = data.setdefault("drive", {})
            drive["gains"] = {**drive.get("gains", {}), **self.gains}
        return {"data": data, "base": str(self.path.parent), "source": self.path.name,
                "speed": self.speeds[speed_index], "fidelity": self.spec.fidelity,
                "index": index, "speed_index": speed_index}

    def keys(self) -> list[tuple[int, int]]:
        """Every (sample, speed) pair, in order."""
        return [(i, k) for i in range(self.design.samples) for k in range(len(self.speeds))]


def plan_sweep(path, samples: int | None = None, data: dict | None = None) -> SweepPlan:
    """Read a scene with a ``[sweep]`` table and draw its design.

    Parameters
    ----------
    path : str or Path
        The scene file.
    samples : int, optional
        Overrides ``sweep.samples``.
    data : dict, optional
        The scene's mapping, when it is not to be read from ``path`` (whose directory still
        resolves the cam file and whose name is the scene's default name).

    Raises
    ------
    CamFileError, InputError
        A bad scene or ``[sweep]`` table (one line).
    """
    path = Path(path)
    data = read_toml(path, "scene file") if data is None else data
    scene = parse_scene(data, base=path.parent, source=path.name, path=path.resolve())
    spec = parse_sweep(data, base=path.parent, source=path.name)
    if samples is not None:
        spec = _with_samples(spec, integer("--samples", samples, minimum=1, maximum=1_000_000))
    profile = scene.cam.load_profile()
    speeds = spec.speeds_per_second(scene, profile.master_period)
    # Refused before the design is drawn: a design never has more rows than asked for, and
    # drawing a million rows only to refuse them took seconds.
    if spec.samples * len(speeds) > MAX_RUNS:
        raise InputError(f"sweep: {spec.samples} samples x {len(speeds)} speeds = "
                         f"{spec.samples * len(speeds)} runs should be <= {MAX_RUNS}")
    nominal = {name: nominal_value(data, name) for name, _ in spec.vary}
    drawn = design(spec.method, spec.distributions, spec.samples, spec.seed,
                   {k: v for k, v in nominal.items() if v is not None})
    gains = nominal_gains(scene.with_master_speed(speeds[0]).with_fidelity(spec.fidelity)) \
        if spec.tuning == "nominal" else None
    return SweepPlan(path=path, data=data, scene=scene, spec=spec, design=drawn,
                     speeds=tuple(speeds), unit=profile.master_unit, nominal=nominal, gains=gains)


def _with_samples(spec: SweepSpec, samples: int) -> SweepSpec:
    from dataclasses import replace

    return replace(spec, samples=samples)


def nominal_gains(scene: Scene) -> dict:
    """The nominal machine's tuning, as the [drive.gains] that pin it in every sample: the
    gains of the report's ``tuning`` object (the rig's commissioning of the nominal scene).

    Raises
    ------
    SimulationError
        The rig's report has no ``tuning`` object with those gains.
    """
    from hil_sim.rig import run_scene

    tuning = run_scene(scene, path="fast").to_dict().get("tuning")
    if not (isinstance(tuning, dict) and all(k in tuning for k in PINNED_GAINS[:3])):
        raise SimulationError("sweep.tuning: 'nominal' needs the report's tuning object "
                              f"({', '.join(PINNED_GAINS[:3])}), which this rig does not give")
    gains = {k: tuning[k] for k in PINNED_GAINS if tuning.get(k) is not None}
    notch = gains.get("notch_hz")
    if isinstance(notch, (list, tuple)):  # the tuner reports its notches as a list
        gains["notch_hz"] = notch[0] if len(notch) == 1 else (0.0 if not notch else list(notch))
    return {k: float(v) if isinstance(v, (int, float)) else v for k, v in gains.items()}


# --- the results file -------------------------------------------------------------------------
def _header(plan: SweepPlan) -> dict:
    return {"kind": "sweep", "fingerprint": plan.fingerprint, "scene": plan.scene.name,
            "samples": plan.design.samples, "speeds": list(plan.speeds)}


def read_results(file: Path, plan: SweepPlan) -> dict:
    """The results already in ``file`` {(index, speed_index): result}, for ``--resume``; a
    last line cut short by an interruption is dropped (it is run again)."""
    results: dict = {}
    try:
        lines = file.read_text().splitlines()
    except FileNotFoundError:
        return results
    except OSError as exc:
        raise InputError(f"--resume: {file} cannot be read: {exc.strerror or exc}") from None
    if not lines:
        return results
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError:
        header = None
    if not isinstance(header, dict) or header.get("fingerprint") != plan.fingerprint:
        raise InputError(f"--resume: {file} is the results file of another sweep (another "
                         "scene, [sweep] table or --samples); give another -o directory")
    for line in lines[1:]:
        try:
            row = json.loads(line)
            results[(int(row["index"]), int(row["speed_index"]))] = row
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            continue  # a line cut by an interruption: the sample runs again
    return results


class _ResultsLog:
    """Appends one JSON line per result and flushes it, so an interruption loses at most the
    line being written. The directory is made (and so checked) at once; the file is opened
    with the first result, so a sweep that never started (a scheduler that cannot be reached)
    leaves no results file behind."""

    def __init__(self, file: Path, plan: SweepPlan, fresh: bool) -> None:
        self._file, self._plan, self._fresh, self._handle = file, plan, fresh, None
        try:
            file.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"-o: {str(file.parent)!r} cannot be made: "
                             f"{exc.strerror or exc}") from None

    def _open(self) -> None:
        file = self._file
        try:
            self._handle = open(file, "w" if self._fresh else "a", encoding="utf-8")
            if self._fresh:
                self._line(_header(self._plan))
            elif file.stat().st_size and not file.read_bytes().endswith(b"\n"):
                self._handle.write("\n")  # a line cut by the interruption stays a line of its own
        except OSError as exc:
            raise InputError(f"-o: {str(file)!r} cannot be written: {exc.strerror or exc}") from None

    def _line(self, row: dict) -> None:
        self._handle.write(json.dumps(row, sort_keys=True, allow_nan=False) + "\n")
        self._handle.flush()

    def write(self, row: dict) -> None:
        if self._handle is None:
            self._open()
        self._line(row)

    def close(self) -> None:
        if self._handle is not None:
            self._handle.close()


def result_rows(directory) -> list[dict]:
    """The results in ``directory``'s results file, sorted by sample and speed (the last line
    of each pair wins; the header and lines cut short are skipped)."""
    rows: dict = {}
    try:
        lines = (Path(directory) / RESULTS_FILE).read_text().splitlines()[1:]
    except OSError as exc:
        raise InputError(f"-o: {str(directory)!r} holds no readable {RESULTS_FILE}: "
                         f"{exc.strerror or exc}") from None
    for line in lines:
        try:
            row = json.loads(line)
            rows[(int(row["index"]), int(row["speed_index"]))] = row
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            continue
    return [rows[key] for key in sorted(rows)]


# --- running ----------------------------------------------------------------------------------
def _dask():
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise InputError(INSTALL_HINT) from None
    return Client, LocalCluster, as_completed


def open_client(workers: int | None = None, scheduler: str | None = None):
    """A Dask client, and the LocalCluster it runs on (None with ``scheduler``).

    ``workers`` processes of one thread each (default: the machine's cores); or the cluster
    whose scheduler listens at ``scheduler`` (``tcp://host:8786``).
    """
    Client, LocalCluster, _ = _dask()
    if scheduler is not None:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler: {scheduler!r} cannot be reached: "
                             f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
    with warnings.catch_warnings():
        # Without a dashboard the scheduler still serves /health over HTTP, on 8787 or, when
        # another cluster holds it, on a free port with a warning: no business of the sweep's.
        warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.CRITICAL)
    return Client(cluster), cluster


def run_sweep(path, *, samples: int | None = None, workers: int | None = None,
              scheduler: str | None = None, directory=None, resume: bool = False,
              progress=None, rerun_worst: bool = True, data: dict | None = None) -> dict:
    """Run a scene's sweep and return its summary (see :func:`summarize`).

    Parameters
    ----------
    path : str or Path
        A scene file with a ``[sweep]`` table.
    samples : int, optional
        Overrides ``sweep.samples``.
    workers : int, optional
        Worker processes of the LocalCluster (default: one per core).
    scheduler : str, optional
        The address of a running Dask scheduler instead (its workers need ecam installed).
    directory : str or Path, optional
        Where ``results.jsonl``, ``summary.json`` and ``worst_sample.json`` go (default:
        ``<scene name>-sweep`` here).
    resume : bool
        Continue the results file in ``directory`` (only the missing samples run).
    progress : callable, optional
        ``progress(done, total, seconds)`` after every result.
    rerun_worst : bool
        Run the worst sample again over CANopen and keep its report.
    data : dict, optional
        The scene's mapping instead of the file's (see :func:`plan_sweep`).

    Returns
    -------
    dict
        The summary (:func:`summarize`), and ``timing``: ``wall_s`` (the whole call),
        ``cluster_s`` (starting the cluster), ``runs``, ``runs_per_s`` (over the wall time)
        and ``steady_runs_per_s`` (from the first result to the last).

    Raises
    ------
    InputError
        A bad scene or ``[sweep]`` table, dask missing, a scheduler that cannot be reached, a
        results file that exists without ``resume`` or is another sweep's.
    """
    if workers is not None:
        workers = integer("--workers", workers, minimum=1, maximum=1024)
    if workers is not None and scheduler is not None:
        raise InputError("--workers: give either --workers (a local cluster) or --scheduler")
    _dask()  # one line on what to install, before any work
    plan = plan_sweep(path, samples, data)
    directory = Path(directory) if directory is not None else Path(f"{plan.scene.name}-sweep")
    file = directory / RESULTS_FILE
    if file.exists() and not resume:
        raise InputError(f"-o: {str(file)!r} exists; give --resume to continue that sweep, or "
                         "another -o directory")
    results = read_results(file, plan) if resume else {}
    pending = [key for key in plan.keys() if key not in results]
    log = _ResultsLog(file, plan, fresh=not (resume and file.exists()
                                             and file.stat().st_size > 0))
    start = time.perf_counter()
    timing = {}
    try:
        if pending:
            timing = _run_pending(plan, pending, results, log, workers, scheduler, progress, start)
    finally:
        log.close()
    wall_s = time.perf_counter() - start
    summary = summarize(plan, results)
    if rerun_worst and summary["worst_sample"] is not None:
        summary["worst_sample"].update(_rerun_worst(plan, summary["worst_sample"], directory))
    write_files({directory / SUMMARY_FILE: json.dumps(summary, indent=2, sort_keys=True,
                                                       allow_nan=False) + "\n"})
    ran = len(pending)
    summary_timing = {"wall_s": wall_s, "runs": ran,
                      "runs_per_s": ran / wall_s if wall_s > 0 and ran else None,
                      "workers": workers, "scheduler": scheduler,
                      "directory": str(directory), **timing}
    return {**summary, "timing": summary_timing}


def _run_pending(plan, pending, results, log, workers, scheduler, progress, start) -> dict:
    """Run the pending tasks on Dask, log each result as it comes; return the timing."""
    _, _, as_completed = _dask()
    client, cluster = open_client(workers, scheduler)
    timing = {"cluster_s": time.perf_counter() - start}
    first = last = None
    try:
        futures = client.map(run_sample, [plan.task(i, k) for i, k in pending], pure=False)
        total, done = len(plan.keys()), len(plan.keys()) - len(pending)
        for future in as_completed(futures):
            try:
                row = future.result()
            except Exception as exc:  # the worker died or the result could not come back
                key = pending[futures.index(future)]
                row = {"index": key[0], "speed_index": key[1], "passed": False, "checks": [],
                       "error": f"its worker failed: {type(exc).__name__}: "
                                f"{str(exc).splitlines()[0] if str(exc) else ''}", "seconds": 0.0}
            row["speed"] = plan.speeds[row["speed_index"]]
            row["values"] = plan.design.sample(row["index"])
            row["seed"] = plan.design.seeds[row["index"]]
            log.write(row)
            results[(row["index"], row["speed_index"])] = row
            last = time.perf_counter()
            first = first if first is not None else last
            done += 1
            if progress is not None:
                progress(done, total, time.perf_counter() - start)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    if first is not None and last > first and len(pending) > 1:
        timing["steady_runs_per_s"] = (len(pending) - 1) / (last - first)
    return timing


def sample_scene(plan: SweepPlan, index: int, speed_index: int = 0) -> Scene:
    """Sample ``index`` of the sweep alone, at judged speed ``speed_index``, as the scene its
    worker ran (its values, the pinned gains if any, the speed and the fidelity): a sample is
    reproducible from the scene, the ``[sweep]`` table and its index.

    Raises
    ------
    InputError
        An index outside the design, or a sample that does not read (its one-line error).
    """
    integer("sample", index, minimum=0, maximum=plan.design.samples - 1)
    integer("speed_index", speed_index, minimum=0, maximum=len(plan.speeds) - 1)
    task = plan.task(index, speed_index)
    scene = parse_scene(task["data"], base=plan.path.parent, source=plan.path.name)
    return scene.with_master_speed(task["speed"]).with_fidelity(plan.spec.fidelity)


def _rerun_worst(plan: SweepPlan, worst: dict, directory: Path) -> dict:
    """Run the worst sample over CANopen; keep its full report in ``worst_sample.json``."""
    from hil_sim.rig import run_scene

    try:
        report = run_scene(sample_scene(plan, worst["index"], worst["speed_index"]),
                           path="canopen")
    except EcamError as exc:
        return {"canopen": {"error": str(exc).splitlines()[0]}}
    write_files({directory / WORST_FILE: report.to_json()})
    return {"canopen": {"passed": report.passed, "failed": [c.name for c in report.failed],
                        "report": WORST_FILE}}


# --- the summary ------------------------------------------------------------------------------
def _ratio(check: dict) -> float | None:
    value, limit = check.get("value"), check.get("limit")
    if value is None or limit is None or limit == 0:
        return None
    return value / limit


def _severity(row: dict) -> float:
    """How near its limits a sample came: its largest value / limit (NaN when it errored or
    has no rated check)."""
    ratios = [r for r in (_ratio(c) for c in row["checks"]) if r is not None]
    return max(ratios) if ratios else math.nan


def summarize(plan: SweepPlan, results: dict) -> dict:
    """The sweep's verdict, from its results {(index, speed_index): result}.

    Returns
    -------
    dict
        ``scene``, ``method``, ``samples``, ``seed``, ``tuning``, ``fidelity``, ``vary`` (the
        distributions), ``nominal`` (the scene's values), ``speeds`` and ``unit``; at the first
        judged speed: ``speed``, ``yield`` and ``yield_interval`` (Wilson, at ``confidence``),
        ``passed``, ``errors`` (samples that could not run count as not passing),
        ``error_samples`` (the first 20: index and error), ``checks`` (per check: ``name``,
        ``unit``, ``limit``, ``failures``, ``failure_rate``, ``failure_interval``, ``worst``
        and ``min`` / ``median`` / ``max`` of its value), ``sensitivity`` and
        ``worst_sample``; over the speeds: ``by_speed`` (yield at each) and
        ``max_speed_at_yield``.
    """
    spec, drawn = plan.spec, plan.design
    names = list(drawn.names)
    by_speed = []
    for k, speed in enumerate(plan.speeds):
        rows = [results.get((i, k)) for i in range(drawn.samples)]
        ran = [r for r in rows if r is not None]
        passed = sum(1 for r in ran if r["passed"])
        entry = {"speed": speed, "samples": len(ran), "passed": passed,
                 "errors": sum(1 for r in ran if r.get("error"))}
        share = proportion(passed, len(ran), spec.confidence)
        entry["yield"], entry["yield_interval"] = share["value"], share["interval"]
        by_speed.append(entry)
    first = [results.get((i, 0)) for i in range(drawn.samples)]
    ran = [r for r in first if r is not None]
    out = {"scene": plan.scene.name, "method": spec.method, "samples": len(ran),
           "design_samples": drawn.samples, "seed": spec.seed, "tuning": spec.tuning,
           "fidelity": spec.fidelity, "confidence": spec.confidence,
           "vary": {name: d.to_dict() for name, d in spec.vary}, "nominal": plan.nominal,
           "pinned_gains": plan.gains, "speeds": list(plan.speeds), "unit": plan.unit,
           "speed": plan.speeds[0], "yield": by_speed[0]["yield"],
           "yield_interval": by_speed[0]["yield_interval"], "passed": by_speed[0]["passed"],
           "errors": by_speed[0]["errors"],
           "error_samples": [{"index": r["index"], "error": r["error"]} for r in ran
                             if r.get("error")][:20],
           "by_speed": by_speed,
           "max_speed_at_yield": max_speed_at_yield(
               plan.speeds, [e["passed"] for e in by_speed], [e["samples"] for e in by_speed],
               spec.required_yield, spec.confidence)}
    out["checks"] = _check_summary(ran, names, spec.confidence)
    out["sensitivity"] = _sensitivity(plan, first, names)
    worst = _worst(ran)
    out["worst_sample"] = None if worst is None else {
        "index": worst["index"], "speed_index": 0, "speed": plan.speeds[0],
        "seed": drawn.seeds[worst["index"]], "values": drawn.sample(worst["index"]),
        "passed": worst["passed"], "severity": _clean(_severity(worst)),
        "failed": [c["name"] for c in worst["checks"] if not c["passed"]]}
    return _clean(out)


def _worst(rows: list) -> dict | None:
    """The sample that failed hardest: failed before passed, then the largest value / limit."""
    runnable = [r for r in rows if not r.get("error")]
    if not runnable:
        return None

    def key(row):
        severity = _severity(row)
        return (not row["passed"], -math.inf if math.isnan(severity) else severity, -row["index"])

    return max(runnable, key=key)


def _check_summary(rows: list, names: list, confidence: float) -> list[dict]:
    runnable = [r for r in rows if not r.get("error")]
    order: list[str] = []
    for row in runnable:
        for c in row["checks"]:
            if c["name"] not in order:
                order.append(c["name"])
    out = []
    for name in order:
        entries = [(row, c) for row in runnable for c in row["checks"] if c["name"] == name]
        failures = sum(1 for _, c in entries if not c["passed"])
        share = proportion(failures, len(entries), confidence)
        valued = [(row, c) for row, c in entries if c["value"] is not None]
        values = np.array([c["value"] for _, c in valued], dtype=float)
        worst = max(valued, key=lambda rc: (rc[1]["value"], -rc[0]["index"]), default=None)
        limits = sorted({c["limit"] for _, c in entries if c["limit"] is not None})
        out.append({
            "name": name, "unit": entries[0][1]["unit"],
            "limit": limits[0] if len(limits) == 1 else (limits or None),
            "failures": failures, "failure_rate": share["value"],
            "failure_interval": share["interval"],
            "min": float(values.min()) if len(values) else None,
            "median": float(np.median(values)) if len(values) else None,
            "max": float(values.max()) if len(values) else None,
            "worst": None if worst is None else {
                "index": worst[0]["index"], "value": worst[1]["value"],
                "limit": worst[1]["limit"], "ratio": _ratio(worst[1]),
                "passed": worst[1]["passed"], "values": worst[0]["values"]}})
    return out


def _sensitivity(plan: SweepPlan, rows: list, names: list) -> dict:
    """Which fields drive failure: Sobol' indices on a Sobol' design that ran whole, else
    Spearman's rank correlation, of each sample's severity (largest value / limit) and of each
    check's value."""
    severity = np.array([math.nan if r is None or r.get("error") else _severity(r) for r in rows])
    values = plan.design.values
    note = None
    if plan.spec.method == "sobol":
        if np.all(np.isfinite(severity)):
            return {"method": "sobol", "output": "severity",
                    "about": "first-order (S1) and total (ST) Sobol' indices of each sample's "
                             "largest value / limit (SALib, Saltelli design)",
                    "parameters": sobol_sensitivity(names, severity, seed=plan.spec.seed,
                                                    confidence=plan.spec.confidence)}
        note = ("some samples did not run or have no rated check: Sobol' indices need all of "
                "them, so the ranking is Spearman's instead")
    keep = np.isfinite(severity)
    out = {"method": "spearman", "output": "severity",
           "about": "Spearman rank correlation of each varied field with each sample's largest "
                    "value / limit (positive: a larger value brings the machine nearer a limit)",
           "parameters": rank_sensitivity(names, values[keep], severity[keep]), "checks": {}}
    if note:
        out["note"] = note
    check_names = []
    for r in rows:
        for c in (r or {}).get("checks", []):
            if c["name"] not in check_names and c["limit"] is not None:
                check_names.append(c["name"])
    for name in check_names:
        pairs = [(i, next((c["value"] for c in r["checks"] if c["name"] == name), None))
                 for i, r in enumerate(rows) if r is not None and not r.get("error")]
        pairs = [(i, v) for i, v in pairs if v is not None]
        if len(pairs) >= 3:
            index = [i for i, _ in pairs]
            out["checks"][name] = rank_sensitivity(names, values[index], [v for _, v in pairs])
    return out


def _clean(value):
    """JSON-ready: numpy to Python, floats to 10 significant digits, NaN to None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return float(f"{value:.10g}") if math.isfinite(value) else None
    return value


# --- text -------------------------------------------------------------------------------------
def _percent(share) -> str:
    return "n/a" if share is None else f"{100.0 * share:.3g} %"


def format_summary(summary: dict) -> str:
    """The summary as text: yield, per check, sensitivity, speeds, the worst sample."""
    lo_hi = summary["yield_interval"]
    interval = "" if lo_hi is None else (f" ({100 * summary['confidence']:.3g} % Wilson interval "
                                         f"{_percent(lo_hi[0])} .. {_percent(lo_hi[1])})")
    lines = [f"sweep {summary['scene']}: {summary['method']}, {summary['samples']} samples, "
             f"seed {summary['seed']}, tuning {summary['tuning']}, fidelity {summary['fidelity']}",
             f"yield at {summary['speed']:.6g} {summary['unit']}/s: {_percent(summary['yield'])}"
             f"{interval}; {summary['passed']} passed"
             + (f", {summary['errors']} could not run" if summary["errors"] else "")]
    lines.append("checks (failure rate, worst sample):")
    for c in summary["checks"]:
        worst = c["worst"]
        text = f"  {c['name']}: fails {_percent(c['failure_rate'])} ({c['failures']})"
        if worst is not None and worst["value"] is not None:
            unit = f" {c['unit']}" if c["unit"] else ""
            text += f", worst #{worst['index']} {worst['value']:.6g}{unit}"
            if worst["limit"] is not None:
                text += f" against {worst['limit']:.6g}{unit}"
        lines.append(text)
    sens = summary["sensitivity"]
    lines.append(f"sensitivity ({sens['method']}, of {sens['output']}):")
    for p in sens["parameters"]:
        if sens["method"] == "sobol":
            lines.append(f"  {p['name']}: ST {_num(p['ST'])} +- {_num(p['ST_conf'])}, "
                         f"S1 {_num(p['S1'])} +- {_num(p['S1_conf'])}")
        else:
            lines.append(f"  {p['name']}: rho {_num(p['spearman'])}")
    if len(summary["by_speed"]) > 1:
        lines.append("yield by speed:")
        for e in summary["by_speed"]:
            lines.append(f"  {e['speed']:.6g} {summary['unit']}/s: {_percent(e['yield'])}"
                         + ("" if e["yield_interval"] is None else
                            f" ({_percent(e['yield_interval'][0])} .. "
                            f"{_percent(e['yield_interval'][1])})"))
    fastest = summary["max_speed_at_yield"]
    lines.append(f"fastest speed with a yield of at least {_percent(fastest['required'])} "
                 f"(at {100 * summary['confidence']:.3g} % confidence): "
                 + ("none of the judged speeds" if fastest["speed"] is None
                    else f"{fastest['speed']:.6g} {summary['unit']}/s")
                 + ("" if fastest["next_speed"] is None
                    else f" (not reached at {fastest['next_speed']:.6g})")
                 + ("" if fastest["speed_estimate"] is None
                    else f"; observed yield reaches it up to {fastest['speed_estimate']:.6g}"))
    worst = summary["worst_sample"]
    if worst is not None:
        values = ", ".join(f"{k} = {v:.6g}" for k, v in worst["values"].items())
        canopen = worst.get("canopen", {})
        again = ("" if not canopen else f"; over CANopen: {canopen['error']}" if "error" in canopen
                 else f"; over CANopen: {'PASSED' if canopen['passed'] else 'FAILED'}"
                 + (f" ({', '.join(canopen['failed'])})" if canopen["failed"] else "")
                 + f", report {canopen['report']}")
        lines.append(f"worst sample #{worst['index']} ({values}): "
                     f"{'passed' if worst['passed'] else 'failed ' + ', '.join(worst['failed'])}"
                     f"{again}")
    for e in summary["error_samples"][:3]:
        lines.append(f"sample #{e['index']} could not run: {e['error']}")
    timing = summary.get("timing")
    if timing and timing.get("runs"):
        lines.append(f"time: {timing['runs']} runs in {timing['wall_s']:.3g} s, "
                     f"{timing['runs_per_s']:.3g} runs/s (cluster start included); results in "
                     f"{timing['directory']}/")
    return "\n".join(lines) + "\n"


def _num(value) -> str:
    return "n/a" if value is None else f"{value:+.3f}"
