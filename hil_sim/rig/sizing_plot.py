"""The torque-speed panel of a sized scene's figure, as sizing tools draw it: the motor's S1
curve and the peak curve (what the motor and the module give at each speed, the voltage limit
included), the duty cycle's operating points and its RMS point (the mean speed, the thermal
torque). Drawn into an axes of :func:`hil_sim.rig.plot.report_figure`; matplotlib comes with
the axes."""

from __future__ import annotations

import numpy as np

from hil_sim.report import Report
from hil_sim.rig.palette import GRID as _GRID, LIMIT as _LIMIT, PASSED as _PASSED

_POINTS = "#1f77b4"
_S1 = "#8250df"


def has_torque_speed(report: Report) -> bool:
    """True when the report carries a motor's curves (a scene with a ``[motor]``)."""
    return "sizing_curve_rpm" in (report.series or {})


def draw_torque_speed(ax, report: Report) -> None:
    """The panel: |torque| over |speed| of the duty, the S1 and peak curves, the RMS point."""
    s = report.series
    speed = np.abs(np.asarray(s["sizing_speed_rpm"], dtype=float))
    torque = np.abs(np.asarray(s["sizing_torque"], dtype=float))
    rpm = np.asarray(s["sizing_curve_rpm"], dtype=float)
    ax.plot(rpm, s["sizing_peak_torque"], color=_LIMIT, lw=1.4,
            label="peak (motor, module, voltage limit)")
    ax.plot(rpm, s["sizing_s1_torque"], color=_S1, lw=1.4, label="S1 (continuous)")
    ax.plot(speed, torque, ".", ms=2.0, color=_POINTS, label="the cycle's points")
    thermal = _check(report, "motor_thermal")
    motor = ((report.summary.get("sizing") or {}).get("components") or {}).get("motor") or {}
    mean = (motor.get("required") or {}).get("mean_speed_rpm")
    if thermal is not None and thermal.value is not None and mean is not None:
        ax.plot([mean], [thermal.value], "*", ms=11, color=_PASSED if thermal.passed else _LIMIT,
                label=f"thermal {thermal.value:.3g} N m at the mean {mean:.4g} rpm")
    failed = [c.name for c in report.checks if c.name in _SIZING and not c.passed]
    title = ("torque-speed: " + (", ".join(failed) + " FAILED" if failed else "sizing passed"))
    ax.set_title(title, loc="left", fontsize=9, color=_LIMIT if failed else _PASSED)
    ax.set_xlabel("motor speed [rpm]", fontsize=8.5)
    ax.set_ylabel("motor torque [N m]", fontsize=8.5)
    ax.set_xlim(0.0, float(rpm[-1]) * 1.02)
    top = max(float(np.nanmax(s["sizing_peak_torque"][np.isfinite(s["sizing_peak_torque"])],
                               initial=0.0)), float(torque.max(initial=0.0)))
    ax.set_ylim(0.0, 1.1 * top if top > 0 else 1.0)
    ax.tick_params(labelsize=8)
    ax.grid(True, color=_GRID, lw=0.5)
    ax.legend(loc="upper right", fontsize=7.5, framealpha=0.85)


_SIZING = ("motor_thermal", "motor_speed_torque", "motor_speed", "drive_current",
           "drive_peak_current", "regeneration", "gearhead_torque")


def _check(report: Report, name: str):
    return next((c for c in report.checks if c.name == name), None)
