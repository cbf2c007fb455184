"""The drive-side cam: a table blob downloaded into 0x2000 is verified with
:meth:`ecam.CamTable.from_bytes` into a pending slot and activated atomically by writing 1 to
0x2001:01; a bad, truncated or aborted download is refused and the running table keeps running.
With cam mode 0x2004 = 1 the target is the cam at the master position 0x2003.

A queued switch (issue 23): writing 3 to 0x2001:01 arms the pending table to take over where the
master leaves the running table's period, as a controller's queued ``MC_CamTableSelect`` does
(CODESYS places the new cam "exactly at the end of the previous one"; Rockwell's pending cam takes
effect when the master passes the profile's end; TwinCAT MC3 ``ECamActivationMode.AtBoundary``:
"when either the start or end of the cam table is crossed"). The rule is the firmware's,
:class:`ecam.table_pair.SwitchPair` (``ecam_table_pair.c``), in both directions of master travel:
the period is the one holding the master of the last cycle before the command; going forwards the
pending table takes over at the boundary count itself, going backwards at the count below it,
placed at the boundary either way; a jump over several periods switches at the first boundary; a
table that does not repeat has one period, its master range, and armed after the master left it
the pending table takes over at the next cycle's master. Writing 4 arms it to take over where the
master crosses 0x2001:06, either way (TwinCAT ``MC_CAMACTIVATION_ATMASTERAXISPOS``; MC3
``ECamActivationMode.AtMasterAbsolutePosition``: "Activation occurs when master axis position
crosses the activation position"), placed at that position. 0x2001:02 shows
:data:`CAM_STATUS_QUEUED` until then. Every activation (1, 3, 4) also takes ``MC_CamIn``'s offsets
and scaling from 0x2001:07..0C (:mod:`hil_sim.drive.cam_coupling`). 0x2001:05 places the table then activated (by 1 or 3) as
PLCopen's ``MasterAbsolute`` / ``SlaveAbsolute`` do: bit 0 master relative (its master 0 at the
activation's master position: the period end, or the master of the cycle for 1), bit 1 slave
relative (the running table's position there added); 0, both absolute, is the drive as before.

A large table is verified off the real-time path when the drive serves an external master on a
thread of its own: verifying a legal blob of 4 194 305 points took seconds inside the SDO handler,
with the drive's lock held, and no SYNC, heartbeat or SDO was served meanwhile (issue 28, item 7).
Past :data:`BACKGROUND_VERIFY_BYTES` the last segment is answered at once, 0x2001:02 shows
:data:`CAM_STATUS_VERIFYING` while a worker thread verifies, and the result is what a small
table's download reports at once: the table pending (activation takes it), or the refusal in
0x2001:02..04 (activation is then refused with 0x08000022, as without a pending table). In
lock-step (the rig) every table is verified at once: the run must not depend on thread timing.
"""

from __future__ import annotations

import logging
import math
import threading

from canopen.sdo import SdoAbortedError

from ecam import CamTable
from ecam.errors import TableFormatError
from hil_sim.drive.cam_coupling import Coupling
from hil_sim.drive.cam_out import CamOut
from hil_sim.drive.objects import (
    ACTIVE_CAM_TABLE_CRC32, CAM_ACTIVATION_POSITION, CAM_COMMAND, CAM_LAST_ERROR_CODE,
    CAM_LAST_ERROR_MESSAGE, CAM_MASTER_OFFSET, CAM_MASTER_SCALING_DENOMINATOR,
    CAM_MASTER_SCALING_NUMERATOR, CAM_MODE, CAM_SLAVE_OFFSET, CAM_SLAVE_SCALING_DENOMINATOR,
    CAM_SLAVE_SCALING_NUMERATOR, CAM_STATUS, CAM_SWITCH_MODE, CAM_TABLE_DOWNLOAD, MASTER_POSITION,
    PENDING_CAM_TABLE_CRC32, PROFILE_ACCELERATION, PROFILE_DECELERATION, PROFILE_JERK,
)
from hil_sim.drive.sdo import ABORT_CANNOT_STORE, ABORT_DEVICE_STATE, ABORT_INVALID_VALUE
from hil_sim.int32 import wrap_int32

#: Cam control 0x2001:01 commands and 0x2001:02 status bits.
CAM_COMMAND_NONE = 0
CAM_COMMAND_ACTIVATE = 1
CAM_COMMAND_DISCARD = 2
CAM_COMMAND_ACTIVATE_AT_PERIOD_END = 3
#: TwinCAT MC_CamActivationMode MC_CAMACTIVATION_ATMASTERAXISPOS ("at a defined master position
#: referring to the absolute master axis position"; MC3 ECamActivationMode.AtMasterAbsolutePosition:
#: "Activation occurs when master axis position crosses the activation position"): 0x2001:06.
CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION = 4
#: PLCopen MC_CamOut: leave the cam and stop, jerk-limited, within 0x6083/0x6084/0x60A4:01
#: (:mod:`hil_sim.drive.cam_out`).
CAM_COMMAND_CAM_OUT = 5
CAM_STATUS_ACTIVE = 0x01
CAM_STATUS_PENDING = 0x02
CAM_STATUS_LAST_DOWNLOAD_REFUSED = 0x04
CAM_STATUS_VERIFYING = 0x08  # a downloaded table is being verified (off the real-time path)
CAM_STATUS_QUEUED = 0x10  # the pending table takes over at the running table's period end
CAM_STATUS_CAM_OUT = 0x20  # the slave has left the cam (stopping or stopped)
#: 0x2001:05 bits: where an activated table's master 0 and slave 0 are.
SWITCH_MASTER_RELATIVE = 0x01
SWITCH_SLAVE_RELATIVE = 0x02

# The kinds of a queued switch (CamSlot.queued).
QUEUED_AT_BOUNDARY = "boundary"
QUEUED_AT_POSITION = "position"

#: A cam-out takes the cam's curvature from its slope this many table counts either side: the
#: slope is Q16, so a difference over a few counts would be mostly its rounding.
CURVATURE_COUNTS = 8

#: Blobs longer than this [bytes] are verified by a worker when the drive runs on its own thread:
#: about 5 400 cubic points, a few milliseconds of verification (a 1 kHz SYNC waits that long).
BACKGROUND_VERIFY_BYTES = 64 * 1024

logger = logging.getLogger(__name__)

#: Cam mode 0x2004: targets from the controller (CSP), or from the drive-side cam.
CAM_MODE_CONTROLLER = 0
CAM_MODE_DRIVE_SIDE = 1

#: 0x2001:04 after a good download (and at power-on).
NO_ERROR_MESSAGE = "no error"

#: The drive-side cam's velocity offset uses the master speed from a tracking observer on the
#: master position (a second-order loop, critically damped, this bandwidth [Hz]): the position
#: arrives in whole counts, and one cycle's increment carries up to one count of quantization,
#: 0.8 % of the speed at 131 counts per 1 ms cycle, in a pattern that repeats at tens of hertz
#: (131, 131, ..., 132) and that a feed-forward passes straight to the torque; a mean over a few
#: cycles only moves that pattern. The observer's type-2 loop follows a constant speed and a
#: constant acceleration without a steady-state speed error, as the master encoder's speed
#: observer of a drive that gears to it does.
MASTER_SPEED_BANDWIDTH_HZ = 20.0

#: A table's slope is Q16: slave counts per master count x 2^16.
_SLOPE_ONE = 65536.0


class CamSlot:
    """The active and the pending cam table, and the master position the cam follows.

    Parameters
    ----------
    values : dict
        The drive's live objects, where the cam control and status objects are kept.
    locked : callable, optional
        ``locked(function)`` calls ``function`` holding the lock that serialises the drive's
        handlers (a worker publishes its result through it); default: call it.
    """

    def __init__(self, values: dict, locked=None) -> None:
        self.values = values
        self._locked = locked or (lambda function: function())
        #: Verify blobs past BACKGROUND_VERIFY_BYTES on a worker thread (the drive on its thread).
        self.background = False
        self.worker: threading.Thread | None = None
        self._generation = 0  # bumped by every download, discard and reset: a stale worker's
        # result is dropped
        self.active_table: CamTable | None = None
        self.pending_table: CamTable | None = None
        self.active_blob: bytes | None = None
        self.pending_blob: bytes | None = None
        # The master: (last position unwrapped from INTEGER32 [counts], observed position [counts],
        # observed speed [counts/s], samples so far up to 2, speed out [counts/s]); empty: take
        # the next position as it is.
        self.master_observer: tuple = ()
        # Where the active table sits (0x2001:05..0C, taken at its activation); the unscaled
        # path's master origin and slave base cached from it [counts].
        self._set_coupling(Coupling())
        # A queued switch: (QUEUED_AT_BOUNDARY, window, ended): SwitchPair's window, the running
        # table's period holding the master of the last cycle before the command [table counts]
        # (window None: no cycle yet, the next one sets it); (QUEUED_AT_POSITION, position,
        # last master) [master counts]; False: none queued.
        self.queued: tuple | bool = False
        # A cam-out: None; (None,) until the next cycle plans it; then [CamOut, cycles since
        # its start, the last target [counts]]. A queued activation (3, 4) is refused meanwhile;
        # 1 engages the pending table there (slave relative: from the last target).
        self.out = None

    def reset(self) -> None:
        """Power-on: no table, none pending (a verification in progress is forgotten)."""
        self._generation += 1
        self.active_table = self.pending_table = None
        self.active_blob = self.pending_blob = None
        self.master_observer = ()
        self._set_coupling(Coupling())
        self.queued = False
        self.out = None

    def forget_master(self) -> None:
        """Take the next master position as it is: the previous ones are stale."""
        self.master_observer = ()

    @property
    def blob(self) -> bytes | None:
        """What an upload of 0x2000 returns: the pending table, else the active one."""
        return self.pending_blob or self.active_blob

    # ------------------------------------------------------------------------ download
    def on_download_refused(self, index: int, code: int, message: str) -> None:
        """SDO server callback: a download was refused before it reached the object."""
        if index == CAM_TABLE_DOWNLOAD.index:
            self.refuse(code, message)

    def refuse(self, code: int, message: str) -> None:
        values = self.values
        values[CAM_LAST_ERROR_CODE] = code
        values[CAM_LAST_ERROR_MESSAGE] = message.encode("ascii", "replace").decode("ascii")
        values[CAM_STATUS] |= CAM_STATUS_LAST_DOWNLOAD_REFUSED

    def verify_download(self, blob: bytes) -> None:
        """Verify a complete download of 0x2000 into the pending slot, or refuse it; a large one
        on a worker when :attr:`background` is set (the download is answered at once)."""
        self._generation += 1
        values = self.values
        if self.background and len(blob) > BACKGROUND_VERIFY_BYTES:
            self.pending_table = self.pending_blob = None
            values[PENDING_CAM_TABLE_CRC32] = 0
            values[CAM_STATUS] = ((values[CAM_STATUS] | CAM_STATUS_VERIFYING)
                                  & ~(CAM_STATUS_PENDING | CAM_STATUS_LAST_DOWNLOAD_REFUSED))
            self.worker = threading.Thread(target=self._verify_in_worker, args=(blob, self._generation),
                                           name="cam-verify", daemon=True)
            self.worker.start()
            return
        try:
            table = CamTable.from_bytes(blob)
        except TableFormatError as exc:
            self.refuse(ABORT_CANNOT_STORE, str(exc))
            raise SdoAbortedError(ABORT_CANNOT_STORE) from None
        self._accept(table, blob)

    def _verify_in_worker(self, blob: bytes, generation: int) -> None:
        try:
            result = CamTable.from_bytes(blob)
        except TableFormatError as exc:
            result = exc
        except Exception as exc:  # noqa: BLE001 - a defect: the download is refused, not lost
            logger.exception("cam table verification")
            result = TableFormatError(f"verification failed: {type(exc).__name__}")
        self._locked(lambda: self._publish(generation, blob, result))

    def _publish(self, generation: int, blob: bytes, result) -> None:
        """The worker's result, unless a later download, a discard or a reset superseded it."""
        if generation != self._generation:
            return
        self.values[CAM_STATUS] &= ~CAM_STATUS_VERIFYING
        if isinstance(result, TableFormatError):
            self.refuse(ABORT_CANNOT_STORE, str(result))
        else:
            self._accept(result, blob)

    def _accept(self, table: CamTable, blob: bytes) -> None:
        self.pending_table = table
        self.pending_blob = blob
        values = self.values
        values[PENDING_CAM_TABLE_CRC32] = table.crc32
        values[CAM_STATUS] = ((values[CAM_STATUS] | CAM_STATUS_PENDING)
                              & ~(CAM_STATUS_LAST_DOWNLOAD_REFUSED | CAM_STATUS_VERIFYING))
        values[CAM_LAST_ERROR_CODE] = 0
        values[CAM_LAST_ERROR_MESSAGE] = NO_ERROR_MESSAGE

    # ----------------------------------------------------------------- live object writes
    def write_command(self, command: int) -> None:
        """0x2001:01: activate or discard the pending table."""
        values = self.values
        if command == CAM_COMMAND_ACTIVATE:
            if self.pending_table is None:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            if self.observing and self.active_table is not None:
                master = self.master_observer[0]  # the master of the last cycle: the switch's
                # after a cam-out the slave is where the stop has brought it, not on the cam
                slave = self.out[2] if self.out is not None and len(self.out) > 2 else self._slave_at(master)
                self._place(master, slave)
            else:  # the engagement: MC_CamIn's StartMode absolute, with its offsets and scaling
                self._place(0, 0, engage=True)
                self.master_observer = ()
            # a switch keeps the master speed observer: the master runs on through it, and a
            # restart would zero the next cycle's velocity offset (the whole feed-forward, one
            # cycle) and then take the speed from one noisy whole-count increment
            self._activate()
        elif command == CAM_COMMAND_ACTIVATE_AT_PERIOD_END:
            if self.pending_table is None or self.active_table is None or self.out is not None:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            # the running period: the one holding the master of the last cycle (SwitchPair's
            # window at the arming); no cycle yet: the next one's, and it cannot switch
            self.queued = ((QUEUED_AT_BOUNDARY, *self._window(self.master_observer[0])) if self.observing
                           else (QUEUED_AT_BOUNDARY, None, None))
            values[CAM_STATUS] |= CAM_STATUS_QUEUED
        elif command == CAM_COMMAND_ACTIVATE_AT_MASTER_POSITION:
            if self.pending_table is None or self.active_table is None or self.out is not None:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            # where the master crosses 0x2001:06, either way, from the master of the last cycle
            self.queued = (QUEUED_AT_POSITION, int(values.get(CAM_ACTIVATION_POSITION, 0)),
                           self.master_observer[0] if self.observing else None)
            values[CAM_STATUS] |= CAM_STATUS_QUEUED
        elif command == CAM_COMMAND_CAM_OUT:
            if self.active_table is None or self.out is not None:
                raise SdoAbortedError(ABORT_DEVICE_STATE)
            # the next cycle takes the cam's state there; a queued switch will not come
            self.out = (None,)
            self.queued = False
            values[CAM_STATUS] = (values[CAM_STATUS] | CAM_STATUS_CAM_OUT) & ~CAM_STATUS_QUEUED
        elif command == CAM_COMMAND_DISCARD:  # a verification in progress too
            self._generation += 1
            self.pending_table = self.pending_blob = None
            self.queued = False
            values[PENDING_CAM_TABLE_CRC32] = 0
            values[CAM_STATUS] &= ~(CAM_STATUS_PENDING | CAM_STATUS_VERIFYING | CAM_STATUS_QUEUED)
        elif command != CAM_COMMAND_NONE:
            raise SdoAbortedError(ABORT_INVALID_VALUE)
        values[CAM_COMMAND] = command

    def _activate(self) -> None:
        """The pending table becomes the active one: one assignment between two cycles, atomic
        for the control loop."""
        values = self.values
        self.active_table, self.active_blob = self.pending_table, self.pending_blob
        self.pending_table = self.pending_blob = None
        self.queued = False
        self.out = None  # a new engagement ends a cam-out
        values[ACTIVE_CAM_TABLE_CRC32] = self.active_table.crc32
        values[PENDING_CAM_TABLE_CRC32] = 0
        values[CAM_STATUS] = ((values[CAM_STATUS] | CAM_STATUS_ACTIVE)
                              & ~(CAM_STATUS_PENDING | CAM_STATUS_QUEUED | CAM_STATUS_CAM_OUT))

    @property
    def observing(self) -> bool:
        return bool(self.master_observer)

    def _place(self, master: int, slave: int, engage: bool = False) -> None:
        """The next table's coordinates for an activation at ``master`` [counts] where the
        running table stands at ``slave`` [counts]: 0x2001:05 (relative or absolute; always
        absolute when ``engage``), the offsets 0x2001:07/08 and the scaling 0x2001:09..0C."""
        values = self.values
        mode = 0 if engage else values.get(CAM_SWITCH_MODE, 0)
        self._set_coupling(Coupling(
            zero=master if mode & SWITCH_MASTER_RELATIVE else 0,
            master_offset=int(values.get(CAM_MASTER_OFFSET, 0)),
            master_ratio=(int(values.get(CAM_MASTER_SCALING_NUMERATOR, 1)),
                          int(values.get(CAM_MASTER_SCALING_DENOMINATOR, 1))),
            base=slave if mode & SWITCH_SLAVE_RELATIVE else 0,
            slave_offset=int(values.get(CAM_SLAVE_OFFSET, 0)),
            slave_ratio=(int(values.get(CAM_SLAVE_SCALING_NUMERATOR, 1)),
                         int(values.get(CAM_SLAVE_SCALING_DENOMINATOR, 1)))))

    def _set_coupling(self, coupling: Coupling) -> None:
        self.coupling = coupling
        self.master_origin = coupling.origin
        self.slave_base = coupling.slave_base
        self.scaled = coupling.scaled

    def _lookup(self, master: int) -> tuple[int, int]:
        """The active table at ``master`` [counts], from its origin (target without the base;
        unscaled)."""
        return self.active_table.lookup(master - self.master_origin, with_slope=True)

    def _slave_at(self, master: int) -> int:
        """The running cam's slave position [counts] at ``master`` [counts]."""
        coupling = self.coupling
        return coupling.y(self.active_table.lookup(coupling.x(master)))

    def _window(self, master: int) -> tuple[int, bool]:
        """The running table's period holding ``master`` [counts]: its start in the table's
        counts (0 for a table that does not repeat: its master range) and whether the master is
        outside it (the profile ended); SwitchPair's ``_window`` and ``_outside``."""
        table = self.active_table
        local = self.coupling.x(master)
        if not table.periodic:
            return 0, not 0 <= local < table.master_counts
        return local - local % table.master_counts, False

    def write_mode(self, mode: int) -> None:
        """0x2004: targets from the controller or from the cam; the cam needs an active table."""
        if mode not in (CAM_MODE_CONTROLLER, CAM_MODE_DRIVE_SIDE):
            raise SdoAbortedError(ABORT_INVALID_VALUE)
        if mode == CAM_MODE_DRIVE_SIDE and self.active_table is None:
            raise SdoAbortedError(ABORT_DEVICE_STATE)
        # the master observer goes on: it watches the master in either mode (observe), so a cam
        # engaged on a moving master starts at its speed
        self.values[CAM_MODE] = mode

    @property
    def drives_the_target(self) -> bool:
        """Cam mode is on and there is a table to follow."""
        return self.values[CAM_MODE] == CAM_MODE_DRIVE_SIDE and self.active_table is not None

    # ------------------------------------------------------------------------- the cycle
    def observe(self, cycle_s: float) -> int:
        """Take this cycle's master position 0x2003 into the speed observer; return it unwrapped
        from INTEGER32 [counts]. The drive calls it every cycle a table is active, in cam mode
        0 too: the controller of a cam-in sends the master during its approach."""
        raw = self.values[MASTER_POSITION]
        observer = self.master_observer
        if observer:
            previous = observer[0]
            master = previous + wrap_int32(raw - wrap_int32(previous))
        else:
            master = raw
        self.master_observer = _observe(observer, master, cycle_s)
        return master

    def target(self, cycle_s: float) -> tuple[int, float]:
        """Target [counts] and velocity offset [counts/s] from the active cam at the master
        position 0x2003, for an interpolation period of ``cycle_s``."""
        master = self.observe(cycle_s)
        if self.out is not None:
            return self._cam_out(master, cycle_s)
        if self.queued is not False:
            self._switch_queued(master)
        # The velocity offset belongs to the target's time, as a controller's does: the cam's
        # slope there times the observed master speed (a scalar lookup takes the table's
        # pure-integer path: no numpy overhead per cycle).
        if self.scaled:
            coupling = self.coupling
            position, slope = self.active_table.lookup(coupling.x(master), with_slope=True)
            return (coupling.y(position),
                    slope * coupling.velocity_ratio * self.master_observer[4] / _SLOPE_ONE)
        target, slope = self._lookup(master)
        velocity = slope * self.master_observer[4] / _SLOPE_ONE
        return target + self.slave_base, velocity

    def _cam_out(self, master: int, cycle_s: float) -> tuple[int, float]:
        """Target and velocity offset of a cam-out: planned in its first cycle from the cam's
        state at this cycle's master, then read back at each cycle's time."""
        out = self.out
        if out[0] is None:
            values = self.values
            try:
                plan = CamOut(self._cam_state(master),
                              int(values.get(PROFILE_ACCELERATION, 1)), int(values.get(PROFILE_DECELERATION, 1)),
                              int(values.get(PROFILE_JERK, 1)))
            except ValueError:  # not within the drive's numbers: it holds the cam's position
                logger.exception("cam-out")
                plan = CamOut((self._slave_at(master), 0.0, 0.0), 1, 1, 1)
            out = self.out = [plan, 0, 0]
        plan, k, _ = out
        position, velocity, _ = plan.state(k * cycle_s)
        out[1], out[2] = k + 1, round(position)
        return out[2], velocity

    def _cam_state(self, master: int) -> tuple[float, float, float]:
        """The cam's slave position, velocity and acceleration [counts, /s, /s^2] at ``master``:
        the table's position and slope, its curvature from the slope CURVATURE_COUNTS either
        side, and the master speed observer's speed state (its output adds 2 omega x the
        error, the whole counts' quantization: +-0.3 % at 37 counts per cycle, a stop's start
        velocity to keep out). The master's acceleration is taken as zero: the observer's
        (omega^2 x the error) carries +-8e3 counts/s^2 of the same quantization per cycle; a
        cam-out during a master ramp starts without slope x the master's acceleration."""
        coupling, table = self.coupling, self.active_table
        x = coupling.x(master)
        position, slope = table.lookup(x, with_slope=True)
        h = CURVATURE_COUNTS
        curvature = (int(table.lookup(x + h, with_slope=True)[1])
                     - int(table.lookup(x - h, with_slope=True)[1])) / (2 * h * _SLOPE_ONE)
        (mn, md), (sn, sd) = coupling.master_ratio, coupling.slave_ratio
        speed = self.master_observer[2] * mn / md  # the table's master coordinate per s
        return (float(coupling.y(position)), sn / sd * slope / _SLOPE_ONE * speed,
                sn / sd * curvature * speed * speed)

    def _switch_queued(self, master: int) -> None:
        """A queued switch: at a period boundary, the pending table takes over in the cycle
        whose master leaves the running period, placed at the boundary crossed (SwitchPair.step
        and _cross); at a master position, in the cycle whose master crosses it, either way,
        placed there (forwards the position itself is the first count past it, as a boundary
        is)."""
        kind, where, state = self.queued
        if kind == QUEUED_AT_POSITION:
            if state is None:  # the first cycle since the command: where the master is
                self.queued = (kind, where, master)
            elif state < where <= master or master < where <= state:
                self._place(where, self._slave_at(where))
                self._activate()
            else:
                self.queued = (kind, where, master)
            return
        if where is None:  # the first cycle since the command sets the period
            self.queued = (kind, *self._window(master))
            return
        coupling = self.coupling
        local = coupling.x(master)
        if state:  # armed after the profile ended: at this cycle's master
            self._place(master, self._slave_at(master))
            self._activate()
            return
        if 0 <= local - where < self.active_table.master_counts:
            return
        # forwards the period's end, backwards its start (each period owns its start)
        boundary = where + self.active_table.master_counts if local >= where else where
        self._place(coupling.master_at(boundary), coupling.y(self.active_table.lookup(boundary)))
        self._activate()


def _observe(observer: tuple, master: int, cycle_s: float) -> tuple:
    """One step of the master speed observer (:data:`MASTER_SPEED_BANDWIDTH_HZ`): the new
    (position, observed position, observed speed, samples, speed out). The first position starts
    it at rest, the second at the speed of its increment, and from the third the loop runs. The
    speed out is the rate of the observed position (the speed state plus the position
    correction), which a constant acceleration leaves without a steady-state error."""
    if not observer:
        return master, float(master), 0.0, 1, 0.0
    last, estimate, speed, samples, _ = observer
    if samples == 1:
        speed = (master - last) / cycle_s
        return master, float(master), speed, 2, speed
    # natural frequency, kept well inside the sampling rate so the discrete loop stays stable
    omega = min(2.0 * math.pi * MASTER_SPEED_BANDWIDTH_HZ, 0.5 / cycle_s)
    predicted = estimate + speed * cycle_s
    error = master - predicted
    correction = 2.0 * omega * error  # critically damped: 2 zeta omega, zeta = 1
    speed += omega * omega * cycle_s * error
    return master, predicted + correction * cycle_s, speed, 2, speed + correction
