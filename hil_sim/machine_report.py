"""The report of a machine run: each axis's report (today's fields), the machine's own checks
(bus, faults) and one verdict; JSON and text.

A machine of one (a scene file in today's format) is reported as the scene alone
(:class:`hil_sim.report.Report`); this report is for machine files.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace

from hil_sim.bus_sizing import spreading_text
from hil_sim.report import Check, Report, _clean


@dataclass
class MachineReport:
    """What a machine run found.

    Attributes
    ----------
    machine : str
        The machine's name.
    axes : list of Report
        One report per axis, in the machine file's order.
    machine_checks : list of Check
        The machine's own checks (``bus_load``, ``late_frames``, ``faults``).
    summary : dict
        The machine's facts: path, cycles, bus (load, late frames per axis, sizing).
    timing : dict
        Wall-clock measurements; not part of the deterministic JSON.
    """

    machine: str
    axes: list
    machine_checks: list
    summary: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)

    @property
    def scene(self) -> str:
        """The machine's name (where a scene's report has the scene's)."""
        return self.machine

    @property
    def cycles(self) -> int:
        """Bus cycles run (fewer than planned when a drive fault stopped the machine)."""
        return min(report.cycles for report in self.axes)

    @property
    def model(self) -> str:
        return "machine"

    @property
    def model_reason(self) -> str:
        return f"a machine of {len(self.axes)} axes: " + "; ".join(
            f"{r.scene}: {r.model_reason}" for r in self.axes)

    @property
    def checks(self) -> list[Check]:
        """The machine's checks, then every axis's, named ``axis.check``."""
        return self.machine_checks + [replace(c, name=f"{r.scene}.{c.name}")
                                      for r in self.axes for c in r.checks]

    @property
    def passed(self) -> bool:
        """True when every check of the machine and of every axis passed."""
        return all(c.passed for c in self.machine_checks) and all(r.passed for r in self.axes)

    @property
    def failed(self) -> list[Check]:
        """The checks that failed (axis checks named ``axis.check``)."""
        return [c for c in self.checks if not c.passed]

    def axis(self, name: str) -> Report:
        """The report of the axis called ``name`` (KeyError if there is none)."""
        for report in self.axes:
            if report.scene == name:
                return report
        raise KeyError(name)

    def check(self, name: str) -> Check:
        """The machine's check ``name``, or ``axis.check`` (KeyError if there is none)."""
        for item in self.checks:
            if item.name == name:
                return item
        raise KeyError(name)

    def to_dict(self, timing: bool = False) -> dict:
        """The report as plain data: ``machine``, ``passed``, ``failed``, ``checks`` (the
        machine's), ``axes`` (each axis's report as :meth:`hil_sim.report.Report.to_dict`)
        and the summary; ``timing=True`` adds the wall-clock sections."""
        out = {"machine": self.machine, "passed": self.passed, "cycles": self.cycles,
               "failed": [c.name for c in self.failed],
               "checks": [c.to_dict() for c in self.machine_checks],
               "axes": [r.to_dict(timing=timing) for r in self.axes]}
        out.update(_clean(self.summary))
        if timing:
            out["timing"] = _clean(self.timing)
        return out

    def to_json(self, timing: bool = False) -> str:
        """Deterministic JSON (sorted keys, floats to 10 significant digits) unless ``timing``."""
        return json.dumps(self.to_dict(timing=timing), indent=2, sort_keys=True,
                          allow_nan=False) + "\n"

    def to_text(self) -> str:
        """The machine's verdict and checks, its bus sizing, then each axis's report."""
        failed = self.failed
        lines = [f"machine {self.machine}: {'PASSED' if self.passed else 'FAILED'} after "
                 f"{self.cycles} cycles, {len(self.axes)} axes"
                 + (f" ({', '.join(c.name for c in failed)} failed)" if failed else "")]
        lines += ["  " + c.line() for c in self.machine_checks]
        sizing = self.summary.get("bus", {}).get("sizing")
        if sizing:
            lines.append(sizing_text(sizing, self.summary["cycle_s"],
                                     self.summary["bus"]["bitrate"]))
        if self.timing:
            t = self.timing
            lines.append(f"time: {t['simulated_s']:.4g} s simulated in {t['wall_s']:.3g} s wall, "
                         f"real-time factor {t['real_time_factor']:.3g}x (loop {t['loop_s']:.3g} s, "
                         f"{t['loop_real_time_factor']:.3g}x real time; {t['path']})")
        for report in self.axes:
            lines.append("")
            lines.append(f"axis {report.scene} (node {report.summary.get('node_id')}, phase "
                         f"{report.summary.get('phase', 0.0):g}):")
            lines += ["  " + line for line in report.to_text().rstrip("\n").split("\n")]
        return "\n".join(lines) + "\n"


def sizing_text(sizing: dict, cycle_s: float, bitrate: int) -> str:
    """The bus sizing in words (:func:`hil_sim.bus_sizing.size_bus`)."""
    more = ", ".join(f"{n} more like {name}" for name, n in sizing["more_axes"].items() if n)
    standard = sizing["min_standard_bitrate"]
    return (f"bus sizing (worst-case bit stuffing): {sizing['bits_per_cycle']} bits of cyclic "
            f"frames per {1e3 * cycle_s:g} ms SYNC period, {sizing['load_percent']:.3g} % of "
            f"{bitrate} bit/s (limit {sizing['limit_percent']:g} %: "
            f"{'fits' if sizing['fits'] else 'DOES NOT FIT'}); needs a SYNC period of at least "
            f"{1e3 * sizing['min_cycle_s']:.3g} ms at {bitrate} bit/s, or at least "
            f"{sizing['min_bitrate']:.6g} bit/s at {1e3 * cycle_s:g} ms ("
            + (f"{standard} bit/s standard" if standard else "beyond 1 Mbit/s") + "); fits "
            + (more or "no more axes") + "".join(f"; {s}" for s in [spreading_text(sizing)] if s))
