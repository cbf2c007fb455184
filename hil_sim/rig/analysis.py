"""From a run's record to its report: one function per check, the JSON summary, the series.

Following error (motor side, from the TPDOs), load-side tracking error against the cam,
coupling torque against its rating, wind-up, torsional resonance against the cam's harmonics,
bus load, torque saturation, faults: each a check with a limit. The coupling checks are
:mod:`ecam.mechanics`'s; this module says where in the run their worst value was.
"""

from __future__ import annotations

import math

import numpy as np

from ecam import mechanics
from hil_sim.report import Check, Report, check
from hil_sim.rig.cam import cam_spectrum
from hil_sim.rig.loop import Record
from hil_sim.rig.plan import PreparedRun
from hil_sim.rig.stability import loop_stability_check
from hil_sim.rig.event_bus import event_sdo
from hil_sim.rig.event_checks import event_checks
from hil_sim.rig.sizing_checks import fill_coupling, sizing_checks
from hil_sim.sync_schedule import TpdoTiming


def analyse(run: PreparedRun, record: Record, setup=None) -> Report:
    """The report of a run: every check, in the report's order, and the summary; with the
    axis's ``setup`` (:class:`hil_sim.control.AxisSetup`), the loop's margins too
    (:func:`hil_sim.rig.stability.loop_stability_check`)."""
    tracking = tracking_error(run, record)
    window = check_window(run, record.cycles)
    peak = mechanics.peak_torque_check(record.peak_coupling_torque,
                                       run.mechanics.coupling_max_torque)
    checks = [
        following_error_check(run, record, window),
        tracking_error_check(run, tracking, window),
        coupling_peak_torque_check(run, peak),
        coupling_rms_torque_check(run, record),
        wind_up_check(run, record, peak),
        resonance_excitation_check(run),
        bus_load_check(run, record),
        motor_saturation_check(run, record),
        faults_check(record, run),
    ]
    if setup is not None:
        checks.append(loop_stability_check(run, setup, record))
    sized, sizing_summary, sizing_series = sizing_checks(run)  # motor, module, gearhead
    checks += sized
    evented, event_summary, event_series = event_checks(run)  # [[event]], [[tappet]]
    checks += evented
    fill_coupling(sizing_summary, checks)
    plan, period = run.plan, run.cam.profile.master_period
    series = {"time_s": (np.arange(record.cycles) + 1.0) * plan.cycle_s,
              "master_position": plan.master_units[:record.cycles] % period,
              "tracking_error": tracking, "coupling_torque": record.coupling_torque,
              "peak_coupling_torque": record.peak_coupling_torque,
              "peak_motor_torque": record.peak_motor_torque,
              "peak_twist": record.peak_twist,
              "following_error": record.following_error, **sizing_series}
    series.update({name: values[:record.cycles] for name, values in event_series.items()})
    return Report(scene=run.scene.name, model=record.model, model_reason=record.model_reason,
                  cycles=record.cycles, checks=checks,
                  summary={**summary(run, record), "sizing": sizing_summary, **event_summary},
                  series=series)


def _at_master(run: PreparedRun, cycle: int) -> str:
    return f"at master {run.master_in_period(cycle):.6g} {run.cam.profile.master_unit}"


def _from_mechanics(result: mechanics.CouplingCheck, detail: str | None = None) -> Check:
    """A report line from a coupling check; ``detail`` replaces the check's own."""
    return Check(result.name, result.value, result.limit, result.passed, result.unit,
                 result.detail if detail is None else detail)


def check_window(run: PreparedRun, cycles: int) -> "Window":
    """The cycles the error checks look at: after ``limits.settle_s``, and for the tracking
    check within ``limits.tracking_window`` of master positions (which may span the seam)."""
    limits = run.scene.limits
    end_s = (np.arange(cycles) + 1.0) * run.plan.cycle_s
    settled = end_s >= limits.settle_s - 1e-12
    words = [f"after {limits.settle_s:g} s"] if limits.settle_s else []
    settled_window = {"after_s": limits.settle_s} if limits.settle_s else None
    tracked = settled
    tracked_window = settled_window
    if limits.tracking_window is not None:
        start, end = limits.tracking_window
        period = run.cam.profile.master_period
        x = run.plan.master_units[:cycles] % period
        a, b = start % period, end % period
        inside = (x >= a) & (x <= b) if a <= b else (x >= a) | (x <= b)
        tracked = settled & inside
        unit = run.cam.profile.master_unit
        tracking_words = words + [f"master {start:g}..{end:g} {unit}"]
        tracked_window = {**(settled_window or {}), "master": [start, end]}
    else:
        tracking_words = words
    return Window(settled, tracked, " and ".join(words), " and ".join(tracking_words),
                  settled_window, tracked_window)


class Window:
    """Which cycles a check looks at (boolean masks), how the report says so, and the
    :attr:`hil_sim.report.Check.window` of the checks that use them."""

    def __init__(self, settled: np.ndarray, tracked: np.ndarray, settled_text: str,
                 tracked_text: str, settled_window: dict | None = None,
                 tracked_window: dict | None = None) -> None:
        self.settled, self.tracked = settled, tracked
        self.settled_text, self.tracked_text = settled_text, tracked_text
        self.settled_window, self.tracked_window = settled_window, tracked_window


def _worst(values: np.ndarray, mask: np.ndarray) -> int | None:
    """Index of the largest magnitude among the masked, finite values; None if there is none."""
    magnitude = np.where(mask & np.isfinite(values), np.abs(values), -1.0)
    worst = int(np.argmax(magnitude)) if magnitude.size else 0
    return worst if magnitude.size and magnitude[worst] >= 0.0 else None


def tracking_error(run: PreparedRun, record: Record) -> np.ndarray:
    """Load position minus the cam's (or the cam-in plan's), per cycle [slave units]."""
    load_units = record.load_angle * run.scene.mechanics.slave_units_per_load_radian
    return load_units - run.plan.reference_units[:record.cycles]


def following_error_check(run: PreparedRun, record: Record, window: Window) -> Check:
    """Largest following error the drive reported (motor side, counts, from its TPDO), after
    the settling time."""
    scene = run.scene
    limit = scene.limits.following_error or scene.drive.following_error_window
    within = f" ({window.settled_text})" if window.settled_text else ""
    if not np.isfinite(record.following_error).any():
        return check("following_error", None, limit, "counts", "no TPDO received")
    worst = _worst(record.following_error, window.settled)
    if worst is None:
        return check("following_error", None, limit, "counts", f"no sample{within}",
                     window.settled_window)
    return check("following_error", abs(record.following_error[worst]), limit, "counts",
                 f"{_at_master(run, worst)}, cycle {worst}{within}", window.settled_window)


def tracking_error_check(run: PreparedRun, tracking: np.ndarray, window: Window) -> Check:
    """Largest load-side tracking error against the limit [slave units], within the tracking
    window and after the settling time."""
    unit = run.cam.profile.slave_unit
    within = f" ({window.tracked_text})" if window.tracked_text else ""
    worst = _worst(tracking, window.tracked)
    if worst is None:
        return check("tracking_error", None, run.scene.limits.tracking_error, unit,
                     f"no sample{within}", window.tracked_window)
    return check("tracking_error", abs(tracking[worst]), run.scene.limits.tracking_error, unit,
                 f"{_at_master(run, worst)}, t {(worst + 1) * run.plan.cycle_s:.6g} s{within}",
                 window.tracked_window)


def coupling_peak_torque_check(run: PreparedRun, peak: mechanics.CouplingCheck) -> Check:
    """The peak coupling torque against the coupling's maximum, where it occurred."""
    return _from_mechanics(peak, _at_master(run, peak.sample))


def coupling_rms_torque_check(run: PreparedRun, record: Record) -> Check:
    """The RMS coupling torque against the coupling's rated torque."""
    return _from_mechanics(mechanics.rms_torque_check(record.coupling_torque,
                                                      run.mechanics.coupling_rated_torque))


def wind_up_check(run: PreparedRun, record: Record, peak: mechanics.CouplingCheck) -> Check:
    """Coupling wind-up: the two-mass model's twist, or peak torque / stiffness when the
    coupling ran as rigid (stiff enough for the rigid model)."""
    twist = record.peak_twist if record.model == "two_mass" else None
    result = mechanics.wind_up_check(run.scene.limits.wind_up_deg,
                                     stiffness=run.mechanics.coupling_stiffness,
                                     peak_torque=peak.value, twist=twist)
    if run.mechanics.coupling_stiffness is None or not record.cycles:
        return _from_mechanics(result)
    # where: the largest twist, or (rigid) the peak torque it was computed from
    worst = int(np.argmax(np.abs(twist))) if twist is not None else peak.sample
    return _from_mechanics(result, f"{result.detail}, {_at_master(run, worst)}, cycle {worst}")


def resonance_excitation_check(run: PreparedRun) -> Check:
    """How strongly the cam's harmonics at this master speed excite the torsional mode."""
    return _from_mechanics(mechanics.resonance_excitation_check(
        run.mechanics.torsional_frequency_hz(), run.cam_hz, cam_spectrum(run.cam.profile),
        run.scene.limits.resonance_excitation_percent))


def bus_load_check(run: PreparedRun, record: Record) -> Check:
    """The busiest cycle's bits against the budget of one cycle at the bitrate."""
    bus = record.bus
    if not bus:  # an information line, not a failure: the bus-free path has no bus
        return check("bus_load", None, None, "%", "not measured: bus-free run")
    detail = (f"{bus['overrun_cycles']} of {bus['cycles']} cycles need more than "
              f"{bus['budget_bits']} bits" + (f", first at cycle {bus['first_overrun_cycle']}"
                                              if bus["overrun_cycles"] else ""))
    late = bus.get("late_set_points", 0) + bus.get("late_tpdos", 0)
    if late:
        detail += (f"; {bus.get('late_set_points', 0)} set points and {bus.get('late_tpdos', 0)} "
                   "TPDOs missed their SYNC (sent after it)")
    sdo_text, needed = event_sdo(run, bus)  # drive-side events' SDO frames (hil_sim.rig.event_bus)
    detail += f"; {sdo_text}" if sdo_text else ""
    value = bus["peak_percent"] if needed is None else max(bus["peak_percent"], needed)
    return check("bus_load", value, run.scene.limits.bus_load_percent, "%", detail)


def motor_saturation_check(run: PreparedRun, record: Record) -> Check:
    """Share of cycles with the motor torque clamped at the drive's limit."""
    saturation = 100.0 * float(np.mean(record.saturated)) if record.cycles else 0.0
    limit = run.mechanics.motor_torque_limit
    detail = f"cycles with the torque clamped at {limit} N m" if limit else "no torque limit"
    clamped = np.flatnonzero(record.saturated)
    if clamped.size:  # where: the first cycle clamped
        detail += f", first {_at_master(run, int(clamped[0]))}, cycle {int(clamped[0])}"
    return check("motor_saturation", saturation, run.scene.limits.motor_saturation_percent, "%",
                 detail)


def missing_status_samples(record: Record, run: PreparedRun | None = None) -> int:
    """Cycles whose TPDOs the controller should have received and did not (``run`` given: only
    the SYNCs the scene's TPDO transmission type sends them on, :mod:`hil_sim.sync_schedule`)."""
    missing = ~np.isfinite(record.statusword)
    if run is not None:
        timing = TpdoTiming.of(run.scene)
        if not timing.every_sync:
            missing &= timing.cycles(record.cycles)
    return int(np.count_nonzero(missing))


def injected(record: Record, run: PreparedRun | None = None) -> str:
    """The injected bus faults by kind, one phrase ("" without fault injection)."""
    if not record.faults:
        return ""
    dropped, delayed = record.faults["dropped"], record.faults["delayed"]
    parts = [f"{n} {kind.upper()} dropped" for kind, n in dropped.items() if n]
    parts += [f"{n} {kind.upper()} delayed" for kind, n in delayed.items() if n]
    missing = missing_status_samples(record, run)
    if missing:
        parts.append(f"{missing} status samples missing")
    if record.faults.get("sync_jitter_s"):
        parts.append(f"SYNC jitter +-{1e6 * record.faults['sync_jitter_s']:.3g} us")
    return ", ".join(parts) if parts else "none happened"


def faults(record: Record) -> list[dict]:
    """The EMCYs with an error code (0x00xx is 'no error / reset'), in the order received."""
    return [{"time_s": t, "code": f"0x{code:04X}"} for t, code in record.emcy if code & 0xFF00]


def faults_check(record: Record, run: PreparedRun | None = None) -> Check:
    """No fault allowed: the count of EMCYs with an error code, or why the run stopped."""
    found = faults(record)
    detail = record.stopped or ("; ".join(f"{f['code']} at {f['time_s']:.6g} s" for f in found)
                                or "none")
    bus = injected(record, run)
    if bus:
        detail += f"; bus faults injected: {bus}"
    return check("faults", len(found), 0, "count", detail)


def summary(run: PreparedRun, record: Record) -> dict:
    """Everything besides the checks that goes into the JSON: master, table, mechanics, bus."""
    scene, plan, table, mech = run.scene, run.plan, run.cam.table, run.mechanics
    profile = run.cam.profile
    units = {"master": profile.master_unit, "slave": profile.slave_unit}
    ran = record.cycles
    cam_hz = run.cam_hz
    torsion_hz = mech.torsional_frequency_hz()
    bus = dict(record.bus)
    bus.update({"setup_frames": record.setup.get("setup_frames"),
                "missing_status_samples": missing_status_samples(record, run),
                "faults": record.faults})
    if "download" in record.setup:
        bus["download"] = record.setup["download"]
    ratio = mech.gear_ratio
    gear = ("no gear (1:1)" if ratio == 1.0 else
            f"{1.0 / ratio:.4g}:1 reduction" if ratio < 1.0 else f"1:{ratio:.4g} speed-up")
    return {
        "cam_mode": scene.cam_mode,
        "path": record.path,
        "cycles_planned": plan.cycles,
        "cycle_s": plan.cycle_s,
        "simulated_s": ran * plan.cycle_s,
        "stopped_early": record.stopped,
        "units": units,
        "master": {"profile": scene.master.profile, "speed": plan.speed_units,
                   "period": profile.master_period,
                   "speed_unit": f"{units['master']}/s", "cam_frequency_hz": cam_hz,
                   # the master's travel, not the cruise speed times the time: a ramp covers less
                   "periods": (abs(float(plan.master_units[ran - 1]) - plan.start_units)
                               / profile.master_period if ran else 0.0)},
        "table": {"interp": table.interp, "points": table.points, "bytes": table.nbytes,
                  "crc32": f"0x{table.crc32:08x}", "master_counts": table.master_counts,
                  "slave_counts_per_unit": run.cam.scale,
                  "max_error_units": table.report.get("max_error_units")},
        "mechanics": {"gear": gear, "gear_ratio": ratio,
                      "inertia_ratio": mech.reflected_inertia() / mech.motor_inertia - 1.0,
                      "torsional_frequency_hz": torsion_hz if math.isfinite(torsion_hz) else None,
                      "torsional_harmonic": mechanics.torsional_harmonic(torsion_hz, cam_hz),
                      "excitation_hz": run.excitation_hz,
                      "coupling_rated_torque": mech.coupling_rated_torque,
                      "coupling_max_torque": mech.coupling_max_torque,
                      "motor_torque_limit": mech.motor_torque_limit,
                      "peak_motor_torque": float(np.max(record.peak_motor_torque)) if ran else 0.0},
        "bus": bus,
        "faults": faults(record),
    }
