"""A machine run: every axis commissioned, prepared and run in lock-step from one virtual
master, bus-free or on one CANopen network (:func:`hil_sim.rig.run.run_axes`: the same loop a
single-axis scene runs, with a list of axes), then each axis's report and the machine's own
checks (bus load with late frames per axis, faults) and its bus sizing."""

from __future__ import annotations

import math
import time

from ecam.errors import InputError
from ecam.validate import choice
from hil_sim.bus_sizing import size_bus
from hil_sim.machine import Machine, load_machine
from hil_sim.machine_report import MachineReport
from hil_sim.report import Check, check
from hil_sim.rig.run import PATHS, ready_axis, report_axis, run_axes


def run_machine(machine, *, path: str = "canopen", tunings=None) -> MachineReport:
    """Run a machine on the rig and return its report.

    Parameters
    ----------
    machine : Machine or str or Path
        A machine, or the path of a machine file (:func:`hil_sim.machine.load_machine`).
    path : {"canopen", "fast"}
        On one virtual CANopen network (the default), or bus-free.
    tunings : list of hil_sim.tuning.Tuning, optional
        Each axis's commissioning, when already known (a search's trials at other master
        speeds of the same machine); None: each axis is commissioned.

    Returns
    -------
    MachineReport

    Raises
    ------
    ecam.errors.EcamError
        A bad machine file, axes that plan different numbers of cycles, or a run that cannot
        go on.
    """
    choice("path", path, PATHS)
    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    wall_start = time.perf_counter()
    tunings = [None] * len(machine.axes) if tunings is None else tunings
    axes = [ready_axis(scene, tuning) for scene, tuning in zip(machine.axes, tunings)]
    counts = {axis.run.scene.name: axis.run.plan.cycles for axis in axes}
    if len(set(counts.values())) > 1:
        raise InputError("duration: " + ", ".join(f"{n} cycles for axis {name}"
                                                  for name, n in counts.items())
                         + " should be one count for the machine (their cams' master periods "
                         "differ: give duration.cycles or duration.seconds)")
    records, timing = run_axes(axes, path)
    reports = []
    for i, (axis, record) in enumerate(zip(axes, records)):
        report = report_axis(axis, record, timing, i, wall_start)
        report.summary["node_id"] = axis.run.scene.drive.node_id
        report.summary["phase"] = axis.run.scene.phase
        reports.append(report)
    summary = {"path": path, "cycle_s": machine.cycle_s,
               "axes_count": len(reports), "bus": _bus_summary(machine, records)}
    wall_s = time.perf_counter() - wall_start
    simulated_s = min(r.cycles for r in reports) * machine.cycle_s
    report = MachineReport(machine=machine.name, axes=reports,
                           machine_checks=[_bus_check(machine, records, reports),
                                           _faults_check(reports)],
                           summary=summary)
    report.timing = {
        "wall_s": wall_s, "loop_s": timing["loop_s"], "setup_s": timing["setup_s"],
        "tuning_s": sum(a.tuning_s for a in axes), "effects_s": sum(a.effects_s for a in axes),
        "axis_s": list(timing["axis_s"]), "simulated_s": simulated_s, "path": path,
        "real_time_factor": simulated_s / wall_s if wall_s > 0 else math.inf,
        "loop_real_time_factor": (simulated_s / timing["loop_s"] if timing["loop_s"] > 0
                                  else math.inf)}
    return report


def _bus_summary(machine: Machine, records: list) -> dict:
    """The machine's bus: load (the same for every axis: one bus), late frames per axis, and
    the sizing from the frames each axis put on it every cycle (bus-free: none measured)."""
    bus = records[0].bus
    if not bus:
        return {"bitrate": machine.bus.bitrate, "measured": False}
    late = {a.name: {"late_set_points": rec.bus["late_set_points"],
                      "late_tpdos": rec.bus["late_tpdos"],
                      "first_late_cycle": rec.bus["first_late_cycle"]}
            for a, rec in zip(machine.axes, records)}
    keys = ("bitrate", "budget_bits", "peak_bits", "peak_percent", "mean_percent",
            "overrun_cycles", "first_overrun_cycle", "frames", "cycles")
    out = {key: bus[key] for key in keys}
    out.update({"measured": True, "late": late,
                "sizing": machine_sizing(machine, [rec.setup["cyclic_frames"] for rec in records])})
    return out


def machine_sizing(machine: Machine, cyclic_frames: list) -> dict:
    """:func:`hil_sim.bus_sizing.size_bus` from each axis's cyclic frames, ``(COB-ID, data
    length, every, phase)`` (:class:`hil_sim.rig.loop.Station`): a COB-ID several axes put
    there (the shared master position) counts once, as the machine's."""
    axes_of = {}
    for frames in cyclic_frames:
        for cob_id, *_ in frames:
            axes_of[cob_id] = axes_of.get(cob_id, 0) + 1
    shared = {cob_id: (length, every, phase) for frames in cyclic_frames
              for cob_id, length, every, phase in frames if axes_of[cob_id] > 1}
    axes = {a.name: [(length, every, phase) for cob_id, length, every, phase in frames
                     if cob_id not in shared]
            for a, frames in zip(machine.axes, cyclic_frames)}
    return size_bus(axes, machine.bus.bitrate, machine.cycle_s, machine.bus_load_percent,
                    shared=list(shared.values()),
                    sync_counter=bool(machine.bus.sync_counter_overflow))


def _bus_check(machine: Machine, records: list, reports: list) -> Check:
    """The busiest cycle against the machine's limit; the axes whose frames came late."""
    bus = records[0].bus
    if not bus:
        return check("bus_load", None, None, "%", "not measured: bus-free run")
    detail = (f"{bus['overrun_cycles']} of {bus['cycles']} cycles need more than "
              f"{bus['budget_bits']} bits")
    late = [f"{r.scene} {rec.bus['late_set_points']} set points and {rec.bus['late_tpdos']} "
            f"TPDOs (first at cycle {rec.bus['first_late_cycle']})"
            for r, rec in zip(reports, records)
            if rec.bus["late_set_points"] or rec.bus["late_tpdos"]]
    detail += ("; late (after their SYNC): " + ", ".join(late)) if late else "; no frame late"
    return check("bus_load", bus["peak_percent"], machine.bus_load_percent, "%", detail)


def _faults_check(reports: list) -> Check:
    """No drive fault on any axis; which axis stopped the machine."""
    counts = {r.scene: r.check("faults").value or 0 for r in reports}
    stopped = next((r.summary.get("stopped_early") for r in reports
                    if r.summary.get("stopped_early")
                    and not r.summary["stopped_early"].startswith("machine stopped")), None)
    detail = ", ".join(f"{name} {int(n)}" for name, n in counts.items())
    if stopped:
        detail += f"; {stopped}"
    return check("faults", sum(counts.values()), 0, "count", detail)
