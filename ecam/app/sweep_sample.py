"""One sample of a sweep, as a worker runs it: a scene mapping in, a small result out.

This is what ``ecam sweep`` ships to its Dask workers (they import this module, so they need
ecam installed); it imports no Dask itself. A sample that cannot run is a result with its
one-line error, never an exception: the sweep goes on.
"""

from __future__ import annotations

import time
from pathlib import Path

from ecam.errors import EcamError


def run_sample(task: dict) -> dict:
    """Run one sample on the rig's bus-free path.

    Parameters
    ----------
    task : dict
        ``data`` (the sample's scene mapping, see :func:`hil_sim.sweep_spec.sample_data`),
        ``base`` and ``source`` (as :func:`hil_sim.parse_scene` takes them), ``speed`` [master
        units/s], ``fidelity``, and ``index`` / ``speed_index`` (returned as given).

    Returns
    -------
    dict
        ``index``, ``speed_index``, ``passed``, ``checks`` (``name``, ``value``, ``limit``,
        ``passed``, ``unit``, as in the report's JSON), ``tuning`` (the sample's gains and
        margins, where the report has a ``tuning`` object), ``error`` (one line, or None) and
        ``seconds`` (wall time).
    """
    from hil_sim.rig import run_scene
    from hil_sim.scene import parse_scene

    start = time.perf_counter()
    out = {"index": task["index"], "speed_index": task["speed_index"], "passed": False,
           "checks": [], "error": None}
    try:
        scene = parse_scene(task["data"], base=Path(task["base"]), source=task["source"])
        scene = scene.with_master_speed(task["speed"]).with_fidelity(task["fidelity"])
        report = run_scene(scene, path="fast")
        out["passed"] = report.passed
        data = report.to_dict()
        out["checks"] = [{key: c[key] for key in ("name", "value", "limit", "passed", "unit")}
                         for c in data["checks"]]
        tuning = data.get("tuning")
        if isinstance(tuning, dict):  # the sample's commissioning, where the rig reports one
            out["tuning"] = {key: tuning[key] for key in _TUNING_KEYS if key in tuning}
    except EcamError as exc:
        out["error"] = _one_line(str(exc))
    except Exception as exc:  # a defect in the rig: this sample errors, the sweep goes on
        out["error"] = _one_line(f"the rig crashed: {type(exc).__name__}: {exc}")
    out["seconds"] = time.perf_counter() - start
    return out


#: What a sample's result keeps of its report's ``tuning`` object.
_TUNING_KEYS = ("source", "velocity_kp", "velocity_ki", "position_kp", "notch_hz",
                "phase_margin_deg", "gain_margin_db", "sensitivity_peak")


def _one_line(text: str) -> str:
    line = text.splitlines()[0] if text else "error"
    return line if len(line) <= 300 else line[:297] + "..."
