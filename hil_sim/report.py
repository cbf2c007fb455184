"""The tracking report of a rig run: checks with limits, JSON and text (the figure is
:func:`hil_sim.rig.plot.plot_report`).

The JSON (:meth:`Report.to_json`) is deterministic: the same scene gives the same bytes. Wall
time (real-time factor, where the time went) is measured too, but kept apart under
``timing``: it is printed in the text report and added to the JSON only on request.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

from ecam.export import json_safe
from hil_sim.sizing_text import sizing_lines


@dataclass(frozen=True)
class Check:
    """One line of the report: a measured value against its limit.

    Attributes
    ----------
    name : str
        Stable identifier, e.g. ``"tracking_error"``.
    value : float or None
        Measured value (None when it cannot be measured, e.g. no samples).
    limit : float or None
        Limit; None for an informational check, which always passes.
    passed : bool
    unit : str
    detail : str
        Where or why, one line (e.g. the master position of the worst sample).
    window : dict or None
        The samples the check looked at, when not all of them: ``after_s`` (the settling time
        left out [s]) and ``master`` ([start, end] master positions within the period; end <
        start spans the seam).
    """

    name: str
    value: float | None
    limit: float | None
    passed: bool
    unit: str
    detail: str = ""
    window: dict | None = None

    @property
    def ratio(self) -> float | None:
        """value / limit, when both are known and the limit is not zero."""
        if self.value is None or self.limit is None or self.limit == 0:
            return None
        return self.value / self.limit

    @property
    def margin(self) -> float | None:
        """(limit - value) / limit: the share of the limit left (negative when exceeded);
        None without a value or a non-zero limit."""
        ratio = self.ratio
        return None if ratio is None else 1.0 - ratio

    def to_dict(self) -> dict:
        """The check as the JSON object of ``ecam sim --json``'s ``checks`` list.

        Returns
        -------
        dict
            ``name``, ``value``, ``limit``, ``passed``, ``unit``, ``ratio``, ``margin``,
            ``detail``, and ``window`` when the check looked at part of the samples. Floats are
            cut to 10 significant digits (the same JSON wherever their last bits differ); a value
            that is not finite or not known is None (JSON ``null``).
        """
        out = {"name": self.name, "value": _clean(self.value), "limit": _clean(self.limit),
               "passed": self.passed, "unit": self.unit, "ratio": _clean(self.ratio),
               "margin": _clean(self.margin), "detail": self.detail}
        if self.window is not None:
            out["window"] = _clean(self.window)
        return out

    def line(self) -> str:
        """One line of text: verdict, value, limit and by how much it is exceeded."""
        value = "n/a" if self.value is None else f"{self.value:.6g}"
        if self.limit is None:
            text = f"info  {self.name}: {value} {self.unit} (no limit)"
        else:
            verdict = "PASS" if self.passed else "FAIL"
            text = f"{verdict}  {self.name}: {value} {self.unit}, limit {self.limit:.6g} {self.unit}"
            if not self.passed and self.ratio is not None:
                text += f" (exceeded by {100.0 * (self.ratio - 1.0):.3g} %, x{self.ratio:.3g})"
            elif self.passed and self.margin is not None:
                text += f" (margin {100.0 * self.margin:.3g} %)"
        return text + (f"; {self.detail}" if self.detail else "")


def _relative_part(proof: dict) -> str:
    """The proof's value comparison: how far the furthest check lies from the full model's."""
    if "largest_relative" not in proof:
        return ""
    share = proof["largest_relative"]
    text = (", a value missing where the full model has one" if share is None else
            f", values within {100 * share:.3g} % of the full model's")
    if proof.get("relative_check"):
        text += f" ({proof['relative_check']})"
    return text if proof.get("within_relative", True) else text + " (OUTSIDE THE PROOF)"


def _tuning_line(tuning: dict) -> str:
    """The drive's commissioning in one line (:meth:`hil_sim.tuning.Tuning.to_dict`)."""
    def margin(key: str, unit: str) -> str:
        value = tuning.get(key)
        return "inf" if value is None else f"{value:.3g}{unit}"
    notch = ", ".join(f"{f:.4g} Hz" for f in tuning.get("notch_hz", [])) or "none"
    limits = tuning.get("limits", {})
    text = (f"tuning ({tuning['source']}): velocity loop {tuning['velocity_bandwidth_hz']:.4g} Hz "
            f"(kp {tuning['velocity_kp']:.4g} N m s/rad, ki {tuning['velocity_ki']:.4g} N m/rad), "
            f"position loop {tuning['position_bandwidth_hz']:.4g} Hz (kp "
            f"{tuning['position_kp']:.4g} 1/s), notch {notch}; full model: phase margin "
            f"{margin('phase_margin_deg', ' deg')}, gain margin {margin('gain_margin_db', ' dB')}, "
            f"Ms {margin('sensitivity_peak', '')}")
    if limits:
        text += (f" (limits {limits['phase_margin_deg']:g} deg, {limits['gain_margin_db']:g} dB, "
                 f"{limits['sensitivity_peak']:g})")
    return text + ("" if tuning.get("stable", True) else ", UNSTABLE")


def check(name: str, value, limit, unit: str, detail: str = "", window: dict | None = None) -> Check:
    """A check that passes when ``value <= limit`` (always, when ``limit`` is None)."""
    value = None if value is None else float(value)
    limit = None if limit is None else float(limit)
    passed = limit is None or (value is not None and value <= limit)
    return Check(name, value, limit, passed, unit, detail, window)


@dataclass
class Report:
    """What a scene run found.

    Attributes
    ----------
    scene : str
        Scene name.
    model, model_reason : str
        Plant model that ran and why (from :func:`hil_sim.plant.choose_model`).
    cycles : int
        Bus cycles simulated (fewer than planned when a fault stopped the run).
    checks : list of Check
    summary : dict
        Everything else that goes into the JSON (master, table, mechanics, bus, faults).
    timing : dict
        Wall-clock measurements; not part of the deterministic JSON.
    series : dict of str to numpy.ndarray
        Per-cycle records for plots (not serialized).
    """

    scene: str
    model: str
    model_reason: str
    cycles: int
    checks: list[Check]
    summary: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """True when every check passed."""
        return all(c.passed for c in self.checks)

    @property
    def failed(self) -> list[Check]:
        """The checks that failed."""
        return [c for c in self.checks if not c.passed]

    def check(self, name: str) -> Check:
        """The check called ``name`` (KeyError if there is none)."""
        for item in self.checks:
            if item.name == name:
                return item
        raise KeyError(name)

    def to_dict(self, timing: bool = False) -> dict:
        """The report as plain data; ``timing=True`` adds the wall-clock section."""
        out = {"scene": self.scene, "model": self.model, "model_reason": self.model_reason,
               "cycles": self.cycles, "passed": self.passed,
               "failed": [c.name for c in self.failed],
               "checks": [c.to_dict() for c in self.checks]}
        out.update(_clean(self.summary))
        if timing:
            out["timing"] = _clean(self.timing)
        return out

    def to_json(self, timing: bool = False) -> str:
        """Deterministic JSON (sorted keys, floats to 10 significant digits) unless ``timing``."""
        return json.dumps(self.to_dict(timing=timing), indent=2, sort_keys=True,
                          allow_nan=False) + "\n"

    def _effect_lines(self) -> list[str]:
        """The effects that ran and were left out, and why."""
        effects = self.summary.get("effects")
        if not effects:
            return []
        head = f"effects (fidelity {self.summary.get('fidelity')}"
        proof = self.summary.get("fidelity_proof")
        if proof:
            cycles = f" of {proof['cycles']} cycles" if proof.get("cycles") else ""
            head += (f", measured on {proof['runs']} bus-free runs{cycles}; reduced against full model: "
                     f"largest difference {100 * proof['largest_difference']:.3g} % of a limit"
                     + (f" ({proof['check']})" if proof.get("check") else "")
                     + _relative_part(proof)
                     + (", same verdicts" if proof["same_verdicts"] else ", VERDICTS DIFFER"))
        lines = [head + "):"]
        for e in effects:
            state = "in " if e["included"] else "out"
            source = e.get("source") or ""
            # whose value it is: the scene's, or the rig's documented default (hil_sim.effects)
            origin = ("" if source == e["why"] else " (scene)" if source == "scene" else
                      " (default)" if source.startswith("default") else "")
            lines.append(f"  {state}  {e['name']}: {e['value']}{origin}; {e['why']}")
        return lines

    def to_text(self) -> str:
        """A human summary: verdict, model, every check, bus and timing."""
        lines = [f"scene {self.scene}: {'PASSED' if self.passed else 'FAILED'} after "
                 f"{self.cycles} cycles"
                 + (f" ({', '.join(c.name for c in self.failed)} failed)" if self.failed else ""),
                 f"model: {self.model_reason}"]
        stopped = self.summary.get("stopped_early")
        if stopped:
            lines.append(f"stopped early: {stopped}")
        mechanics = self.summary.get("mechanics", {})
        if "gear" in mechanics:
            lines.append(f"machine: {mechanics['gear']}, load/motor inertia ratio "
                         f"{mechanics['inertia_ratio']:.3g}")
        master = self.summary.get("master", {})
        if master.get("periods") is not None and master.get("speed") is not None:
            # the master's travel, which a start ramp or a cam-in's approach leaves short of
            # the periods at cruise speed that a duration in master_periods asks for
            lines.append(f"master: {master.get('profile')}, cruise {master['speed']:.6g} "
                         f"{master.get('speed_unit', '')}, travelled {master['periods']:.3g} periods"
                         + ("" if master.get("profile") == "constant" else
                            " (the start or the cam-in took part of the run's time)"))
        lines += self._effect_lines()
        if self.summary.get("tuning"):
            lines.append(_tuning_line(self.summary["tuning"]))
        lines += ["  " + c.line() for c in self.checks]
        lines += sizing_lines(self.summary.get("sizing"))
        bus = self.summary.get("bus", {})
        if bus:
            lines.append(f"bus: {bus.get('bitrate')} bit/s, {bus.get('budget_bits')} bits per "
                         f"cycle, peak {bus.get('peak_percent', 0):.3g} %, mean "
                         f"{bus.get('mean_percent', 0):.3g} %, {bus.get('overrun_cycles')} "
                         "cycles over budget")
        if self.timing:
            t = self.timing
            lines.append(f"time: {t.get('simulated_s', 0):.4g} s simulated in "
                         f"{t.get('wall_s', 0):.3g} s wall, real-time factor "
                         f"{t.get('real_time_factor', 0):.3g}x (effects measured "
                         f"{t.get('effects_s', 0):.3g} s; loop {t.get('loop_s', 0):.3g} s: "
                         f"servo/plant {t.get('axis_s', 0):.3g} s, bus+CANopen "
                         f"{t.get('protocol_s', 0):.3g} s, {t.get('loop_real_time_factor', 0):.3g}x "
                         f"real time; setup {t.get('setup_s', 0):.3g} s, "
                         f"analysis {t.get('analysis_s', 0):.3g} s)")
        return "\n".join(lines) + "\n"


def _clean(value):
    """JSON-ready copy (:func:`ecam.export.json_safe`: numpy scalars to Python, NaN to None) with
    floats cut to 10 significant digits and keys made strings, so the JSON is the same bytes
    wherever the last bits of a float differ."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    value = json_safe(value)
    return float(f"{value:.10g}") if isinstance(value, float) else value
