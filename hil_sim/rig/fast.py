"""The bus-free path: the drive's control loop and plant fed the same set points as over
CANopen, without frames.

A run over the virtual bus spends most of its time on frames (packing, the bus, canopen's
dispatch); the physics is a fraction of it. This path gives the axis exactly what the drive's
CSP cycle gives it (:meth:`hil_sim.drive.VirtualDrive.run_cycle`): the set point as the RPDO
carries it (INTEGER32 target and velocity offset), or, drive-side, the target the drive's own
cam slot computes from the master position; the same :class:`~hil_sim.control.AxisSetup`, the
same interpolation period as the drive decodes it from 0x60C2, and the drive's following-error
fault (window 0x6065, time-out 0x6066 = 0). With a fault-free bus its record's physics is
bit-identical to the CANopen run's (tested); the rig uses it to measure effects
(:mod:`hil_sim.rig.fidelity`) and for find-max-speed's bisection (:mod:`hil_sim.rig.search`).
What it does not have: bus faults, bus load and arbitration, the set-up by SDO.
"""

from __future__ import annotations

import math

from hil_sim.control import AxisSetup
from hil_sim.drive.cam_slot import CAM_COMMAND_ACTIVATE, CAM_MODE_DRIVE_SIDE, CamSlot
from hil_sim.drive.cia402 import (
    OPERATION_ENABLED, STATUSWORD_OF_STATE, SW_FOLLOWING_COMMAND, SW_REMOTE,
)
from hil_sim.drive.emcy import EMCY_FOLLOWING_ERROR
from hil_sim.drive.objects import (
    CAM_COMMAND, CAM_MODE, CAM_STATUS, CAM_SWITCH_MODE, CAM_TABLE_DOWNLOAD, MASTER_POSITION,
    interpolation_period, interpolation_period_s,
)
from hil_sim.drive.power_state import FOLLOWING_ERROR_WINDOW_OFF
from hil_sim.int32 import wrap_int32
from hil_sim.rig.plan import PreparedRun, wire_set_points
from hil_sim.rig.record import Record, Recorder
from hil_sim.sync_schedule import TpdoTiming

#: The statusword a drive in OPERATION ENABLED, cyclic synchronous position, reports.
_STATUSWORD_CSP = STATUSWORD_OF_STATE[OPERATION_ENABLED] | SW_REMOTE | SW_FOLLOWING_COMMAND


def drive_cycle_s(cycle_s: float) -> float:
    """The interpolation period as the drive decodes it from the 0x60C2 the rig writes."""
    return interpolation_period_s(*interpolation_period(cycle_s))


def run_fast(run: PreparedRun, setup: AxisSetup) -> Record:
    """Run the planned cycles on the axis alone; the record has no bus and no frames.

    Parameters
    ----------
    run : PreparedRun
    setup : AxisSetup
        The axis as the drive would be configured (:func:`hil_sim.rig.run.axis_setup`).

    Returns
    -------
    Record
        ``path`` ``"fast"``; ``bus`` empty; ``statusword`` the drive's CSP statusword.
    """
    scene, plan = run.scene, run.plan
    cycle_s = drive_cycle_s(scene.drive.cycle_s)
    axis = setup.build(cycle_s, plan.initial_counts)
    axis.restart()  # OPERATION ENABLED starts from the actual position, as the drive's
    drive_side = scene.cam_mode == "drive"
    recorder = Recorder(plan.cycles)
    recorder.series["statusword"][:] = _STATUSWORD_CSP
    following = recorder.series["following_error"]
    window = scene.drive.following_error_window
    monitored = window != FOLLOWING_ERROR_WINDOW_OFF
    engage = plan.cycles  # the cycle the drive-side cam takes over (a cam-in's engagement)
    if drive_side:
        masters = wire_set_points(plan, drive_side=True)[0].tolist()
        values = {CAM_STATUS: 0, CAM_MODE: 0, CAM_SWITCH_MODE: 0}
        cam = CamSlot(values)
        commands = _cam_commands(plan)
        cam.verify_download(run.cam.table.to_bytes())
        cam.write_command(CAM_COMMAND_ACTIVATE)
        engage = plan.engaged_from or 0
    # the controller's set points as Python numbers, only for the cycles that use them (drive-
    # side, a cam-in's approach): a list per cycle of a 5e6-cycle run is hundreds of MB
    targets, velocities = (a[:engage].tolist() for a in wire_set_points(plan, drive_side=False))
    stopped = None
    emcy = []
    cycle = axis.cycle
    probe = recorder.probe
    for k in range(plan.cycles):
        if drive_side:  # as the drive's CSP cycle: the RPDOs latched, then the cam or the set point
            values[MASTER_POSITION] = masters[k]
            if k == engage:
                cam.write_mode(CAM_MODE_DRIVE_SIDE)
            if k >= engage:
                cycle(*cam.target(cycle_s))
            else:
                cam.observe(cycle_s)
                cycle(targets[k], velocities[k])
            if commands and k in commands:  # the controller's SDO writes after this SYNC
                for command in commands[k]:
                    _write(cam, values, command)
        else:
            cycle(targets[k], velocities[k])
        error = axis.following_error_counts
        following[k] = wrap_int32(error)
        probe(k, axis)
        recorder.ran = k + 1
        if monitored and abs(error) > window:
            # 0x6066 = 0: the drive faults in the cycle the error leaves its window
            time_s = (k + 1) * cycle_s
            emcy.append((round(time_s, 9), EMCY_FOLLOWING_ERROR))
            stopped = f"drive fault 0x{EMCY_FOLLOWING_ERROR:04X} at cycle {k} (t {time_s:.6g} s)"
            break
    timing = TpdoTiming.of(scene)
    if not timing.every_sync:  # what the controller receives: the TPDOs' SYNCs only
        missing = ~timing.cycles(plan.cycles)
        recorder.series["statusword"][missing] = math.nan
        following[missing] = math.nan
    return recorder.record(stopped=stopped, emcy=emcy, model=axis.model,
                           model_reason=axis.model_reason, setup={}, bus={}, faults=None,
                           path="fast")


def _cam_commands(plan) -> dict:
    """cycle -> the drive-side events' commands to the cam slot (:mod:`hil_sim.events`)."""
    out: dict = {}
    for command in (plan.events.drive_commands if plan.events is not None else ()):
        out.setdefault(command.cycle, []).append(command)
    return out


def _write(cam: CamSlot, values: dict, command) -> None:
    """What the drive does with the SDO write of ``command`` (:class:`VirtualDrive`'s writers)."""
    if command.key == tuple(CAM_TABLE_DOWNLOAD):
        cam.verify_download(command.value)
    elif command.key == tuple(CAM_COMMAND):
        cam.write_command(command.value)
    else:
        values[command.key] = command.value
