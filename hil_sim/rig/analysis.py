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


def analyse(run: PreparedRun, record: Record) -> Report:
    """The report of a run: every check, in the report's order, and the summary."""
    tracking = tracking_error(run, record)
    peak = mechanics.peak_torque_check(record.peak_coupling_torque,
                                       run.mechanics.coupling_max_torque)
    checks = [
        following_error_check(run, record),
        tracking_error_check(run, tracking),
        coupling_peak_torque_check(run, peak),
        coupling_rms_torque_check(run, record),
        wind_up_check(run, record, peak),
        resonance_excitation_check(run),
        bus_load_check(run, record),
        motor_saturation_check(run, record),
        faults_check(record),
    ]
    plan, period = run.plan, run.cam.profile.master_period
    series = {"time_s": (np.arange(record.cycles) + 1.0) * plan.cycle_s,
              "master_position": plan.master_units[:record.cycles] % period,
              "tracking_error": tracking, "coupling_torque": record.coupling_torque,
              "peak_coupling_torque": record.peak_coupling_torque,
              "peak_motor_torque": record.peak_motor_torque,
              "following_error": record.following_error}
    return Report(scene=run.scene.name, model=record.model, model_reason=record.model_reason,
                  cycles=record.cycles, checks=checks, summary=summary(run, record),
                  series=series)


def _at_master(run: PreparedRun, cycle: int) -> str:
    return f"at master {run.master_in_period(cycle):.6g} {run.cam.profile.master_unit}"


def _from_mechanics(result: mechanics.CouplingCheck, detail: str | None = None) -> Check:
    """A report line from a coupling check; ``detail`` replaces the check's own."""
    return Check(result.name, result.value, result.limit, result.passed, result.unit,
                 result.detail if detail is None else detail)


def tracking_error(run: PreparedRun, record: Record) -> np.ndarray:
    """Load position minus the cam's (or the cam-in plan's), per cycle [slave units]."""
    load_units = record.load_angle * run.scene.mechanics.slave_units_per_load_radian
    return load_units - run.plan.reference_units[:record.cycles]


def following_error_check(run: PreparedRun, record: Record) -> Check:
    """Largest following error the drive reported (motor side, counts, from its TPDO)."""
    scene = run.scene
    fe = np.abs(record.following_error)
    limit = scene.limits.following_error or scene.drive.following_error_window
    if not np.isfinite(fe).any():
        return check("following_error", None, limit, "counts", "no TPDO received")
    worst = int(np.nanargmax(fe))
    return check("following_error", fe[worst], limit, "counts",
                 f"{_at_master(run, worst)}, cycle {worst}")


def tracking_error_check(run: PreparedRun, tracking: np.ndarray) -> Check:
    """Largest load-side tracking error against the limit [slave units]."""
    worst = int(np.argmax(np.abs(tracking)))
    return check("tracking_error", abs(tracking[worst]), run.scene.limits.tracking_error,
                 run.cam.profile.slave_unit,
                 f"{_at_master(run, worst)}, t {(worst + 1) * run.plan.cycle_s:.6g} s")


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
    return _from_mechanics(mechanics.wind_up_check(
        run.scene.limits.wind_up_deg, stiffness=run.mechanics.coupling_stiffness,
        peak_torque=peak.value, twist=twist))


def resonance_excitation_check(run: PreparedRun) -> Check:
    """How strongly the cam's harmonics at this master speed excite the torsional mode."""
    return _from_mechanics(mechanics.resonance_excitation_check(
        run.mechanics.torsional_frequency_hz(), run.cam_hz, cam_spectrum(run.cam.profile),
        run.scene.limits.resonance_excitation_percent))


def bus_load_check(run: PreparedRun, record: Record) -> Check:
    """The busiest cycle's bits against the budget of one cycle at the bitrate."""
    bus = record.bus
    detail = (f"{bus['overrun_cycles']} of {bus['cycles']} cycles need more than "
              f"{bus['budget_bits']} bits" + (f", first at cycle {bus['first_overrun_cycle']}"
                                              if bus["overrun_cycles"] else ""))
    return check("bus_load", bus["peak_percent"], run.scene.limits.bus_load_percent, "%", detail)


def motor_saturation_check(run: PreparedRun, record: Record) -> Check:
    """Share of cycles with the motor torque clamped at the drive's limit."""
    saturation = 100.0 * float(np.mean(record.saturated)) if record.cycles else 0.0
    limit = run.mechanics.motor_torque_limit
    return check("motor_saturation", saturation, run.scene.limits.motor_saturation_percent, "%",
                 f"cycles with the torque clamped at {limit} N m" if limit else "no torque limit")


def faults(record: Record) -> list[dict]:
    """The EMCYs with an error code (0x00xx is 'no error / reset'), in the order received."""
    return [{"time_s": t, "code": f"0x{code:04X}"} for t, code in record.emcy if code & 0xFF00]


def faults_check(record: Record) -> Check:
    """No fault allowed: the count of EMCYs with an error code, or why the run stopped."""
    found = faults(record)
    return check("faults", len(found), 0, "count",
                 record.stopped or ("; ".join(f"{f['code']} at {f['time_s']:.6g} s" for f in found)
                                    or "none"))


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
                "missing_status_samples": int(np.count_nonzero(~np.isfinite(record.statusword))),
                "faults": record.faults})
    if "download" in record.setup:
        bus["download"] = record.setup["download"]
    return {
        "cam_mode": scene.cam_mode,
        "cycles_planned": plan.cycles,
        "cycle_s": plan.cycle_s,
        "simulated_s": ran * plan.cycle_s,
        "stopped_early": record.stopped,
        "units": units,
        "master": {"profile": scene.master.profile, "speed": plan.speed_units,
                   "speed_unit": f"{units['master']}/s", "cam_frequency_hz": cam_hz,
                   "periods": ran * plan.cycle_s * cam_hz},
        "table": {"interp": table.interp, "points": table.points, "bytes": table.nbytes,
                  "crc32": f"0x{table.crc32:08x}", "master_counts": table.master_counts,
                  "slave_counts_per_unit": run.cam.scale,
                  "max_error_units": table.report.get("max_error_units")},
        "mechanics": {"torsional_frequency_hz": torsion_hz if math.isfinite(torsion_hz) else None,
                      "torsional_harmonic": mechanics.torsional_harmonic(torsion_hz, cam_hz),
                      "excitation_hz": run.excitation_hz,
                      "coupling_rated_torque": mech.coupling_rated_torque,
                      "coupling_max_torque": mech.coupling_max_torque,
                      "motor_torque_limit": mech.motor_torque_limit,
                      "peak_motor_torque": float(np.max(record.peak_motor_torque)) if ran else 0.0},
        "bus": bus,
        "faults": faults(record),
    }
