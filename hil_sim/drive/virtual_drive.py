"""The virtual drive: the protocol services of this package composed around a servo axis, and the
control cycle that SYNC runs."""

from __future__ import annotations

import time

import can
from canopen.objectdictionary import NUMBER_TYPES
from canopen.sdo import SdoAbortedError

from ecam import validate
from hil_sim.bus import SimNetwork, open_virtual_bus
from hil_sim.drive.cia402 import (
    CYCLIC_SYNCHRONOUS_POSITION, ENERGIZED, FAULT, FAULT_REACTION_ACTIVE, OPERATION_ENABLED,
    OPERATIONAL, PRE_OPERATIONAL, QUICK_STOP_ACTIVE, SWITCH_ON_DISABLED,
)
from hil_sim.control import AxisSetup, Gains, ServoAxis
from hil_sim.drive.cam_slot import NO_ERROR_MESSAGE, CamSlot
from hil_sim.drive.emcy import (
    EMCY_COMMUNICATION, EMCY_INTERNAL_SOFTWARE, EMCY_SYNC_DATA_LENGTH, ERROR_REGISTER_COMMUNICATION,
    ERROR_REGISTER_GENERIC, EmcyProducer,
)
from hil_sim.drive.nmt import NmtSlave
from hil_sim.drive.objects import (
    ABORT_CONNECTION_OPTION_CODE, APPLICATION_AREA, CAM_COMMAND, CAM_LAST_ERROR_MESSAGE, CAM_MODE, CAM_TABLE_DOWNLOAD,
    COB_ID_SYNC, COMMUNICATION_AREA, COMMUNICATION_CYCLE_PERIOD, CONTROLWORD, EDS_PATH, FOLLOWING_ERROR_ACTUAL_VALUE,
    INTERPOLATION_TIME_INDEX, INTERPOLATION_TIME_PERIOD, INTERPOLATION_TIME_PERIOD_VALUE,
    MODES_OF_OPERATION, MODES_OF_OPERATION_DISPLAY, MOTOR_RATED_TORQUE, NMT_COB_ID,
    PDO_PARAMETERS, POSITION_ACTUAL_VALUE, PROCESS_OBJECTS, PRODUCER_HEARTBEAT_TIME,
    SDO_RECEIVE_COB_ID, SDO_TRANSMIT_COB_ID, SYNC_COUNTER_OVERFLOW, TARGET_POSITION,
    TORQUE_ACTUAL_VALUE,
    VELOCITY_ACTUAL_VALUE, VELOCITY_OFFSET, interpolation_period_s, load_od,
)
from hil_sim.drive.pdo import PdoEngine, check_cob_id, check_pdo_write
from hil_sim.int32 import saturate_int32, wrap_int32
from hil_sim.drive.power_state import PowerStateMachine
from hil_sim.drive.runner import Runner
from hil_sim.drive.sdo import (
    ABORT_DEVICE_STATE, ABORT_INVALID_VALUE, ABORT_VALUE_TOO_HIGH, ABORT_VALUE_TOO_LOW, DriveNode,
    DriveSdoServer,
    StoredObjects, check_range,
)
from ecam.mechanics import Mechanics

#: 0x6076 is UNSIGNED32 [mN m].
UNSIGNED32_MAX = 0xFFFFFFFF

#: Interpolation periods the drive accepts in 0x60C2 [s].
MIN_INTERPOLATION_PERIOD_S = 1e-5
MAX_INTERPOLATION_PERIOD_S = 1.0


def _default_mechanics():
    # A small servo motor on a rigid load: enough for protocol tests and `hil-sim drive`.
    return Mechanics(motor_inertia=1.2e-4, load_inertia=3.0e-4, motor_damping=1e-4,
                     motor_torque_limit=4.0)


#: Periods of 0x1006 without a SYNC after which the SYNC counts as lost: a late SYNC (jitter) or
#: one lost frame is tolerated, a stopped master is not (CANopenNode allows 1.5 periods).
SYNC_LOSS_PERIODS = 3


class VirtualDrive:
    """A CiA 402 servo drive on a CAN bus (see the :mod:`hil_sim.drive` docstring).

    Parameters
    ----------
    channel : str
        Virtual channel to open when ``bus`` is None.
    node_id : int
        CANopen node id, 1..127.
    bus : can.BusABC, optional
        A bus of the caller's (then ``channel`` is unused and the caller shuts it down).
    mechanics : ecam.mechanics.Mechanics, optional
        The axis; default a small servo on a rigid load.
    gains : hil_sim.control.Gains, optional
        Control gains; default :meth:`Gains.from_mechanics` without velocity feed-forward
        (the master's velocity offset 0x60B1 carries the speed).
    substeps : int
        Controller periods per interpolation period.
    counts_per_motor_rad : float, optional
        Position counts per motor radian (the drive's position factor).
    model : {"auto", "rigid", "two_mass"}
        Plant model, see :class:`hil_sim.control.ServoAxis`.
    excitation_hz : float
        Highest significant cam harmonic, for the "auto" model choice.
    plant_effects, drive_effects, feedforward
        The axis' effects and feed-forward source, see :class:`hil_sim.control.ServoAxis`.
    initial_counts : int
        Position at power-on [counts].
    heartbeat_ms : int, optional
        Producer heartbeat time 0x1017 at power-on (default: the EDS value).
    eds : str or Path, optional
        Object dictionary; default the shipped ``drive.eds``.
    """

    def __init__(self, channel: str = "ecam", node_id: int = 1, bus: can.BusABC | None = None,
                 *, mechanics=None, gains=None, substeps: int = 8,
                 counts_per_motor_rad: float | None = None, model: str = "auto",
                 excitation_hz: float = 0.0, plant_effects=None, drive_effects=None,
                 feedforward: str = "target", initial_counts: int = 0,
                 heartbeat_ms: int | None = None, eds=None) -> None:
        self.node_id = validate.integer("node_id", node_id, minimum=1, maximum=127)  # CiA 301 node ids
        self.mechanics = mechanics if mechanics is not None else _default_mechanics()
        self.gains = gains if gains is not None else Gains.from_mechanics(
            self.mechanics, velocity_feedforward=0.0)
        self.axis_setup = AxisSetup(
            self.mechanics, self.gains, substeps=substeps, counts_per_motor_rad=counts_per_motor_rad,
            model=model, excitation_hz=excitation_hz, plant_effects=plant_effects,
            drive_effects=drive_effects, feedforward=feedforward)
        self._initial_counts = int(initial_counts)
        self._heartbeat_ms_override = heartbeat_ms
        self.time_s = 0.0  # drive time: interpolation periods run so far
        self.cycles = 0
        self.axis_wall_s = 0.0  # wall time spent in ServoAxis.cycle (profiling)
        self.axis: ServoAxis | None = None
        self._wall_clock = False
        self._last_sync_wall: float | None = None  # wall time of the last SYNC (external master)
        self.sync_losses = 0  # SYNC losses detected
        self.sync_length_errors = 0  # SYNCs of the wrong length for 0x1019, not taken as SYNCs
        self._sync_length_reported = False
        self._sync_counting = False  # 0x1019 > 0: every SYNC carries its counter
        # The live objects; one dict for the drive's lifetime, shared by every service.
        self.values: dict[tuple[int, int], object] = {}

        own_bus = bus is None
        bus = open_virtual_bus(channel) if own_bus else bus
        self.network = SimNetwork(bus, self._now)
        self.od = load_od(eds or EDS_PATH, node_id)
        self.node = DriveNode(node_id, self.od)
        self.objects = StoredObjects(self.node)
        self.cam = CamSlot(self.values, locked=self._locked)
        self.nmt = NmtSlave(self.network, node_id, self._now, self._reset, self._nmt_entered)
        self.defects = 0  # exceptions that escaped a handler (each logged, each a fault)
        self.runner = Runner(bus, own_bus, self.network, self._on_idle,
                             f"VirtualDrive-{node_id}", on_defect=self._on_defect)
        self.emcy = EmcyProducer(self.network, self.objects, self.nmt)
        self.state_machine = PowerStateMachine(
            self.values, self.emcy, lambda: self.axis.position_counts, self._on_enable)
        # Live objects whose write does more than store the value (SDO and RPDO alike).
        self._writers = {
            CONTROLWORD: self.state_machine.write_controlword,
            MODES_OF_OPERATION: self.state_machine.write_mode,
            CAM_MODE: self.cam.write_mode,
            CAM_COMMAND: self.cam.write_command,
        }
        self.pdo = PdoEngine(self.network, self.objects, self.values, self.nmt, self.emcy,
                             self._writers, self._on_sync)

        # canopen's SDO server, NMT slave and heartbeat are replaced (see the package docstring).
        self.node.sdo = DriveSdoServer(SDO_RECEIVE_COB_ID + node_id, SDO_TRANSMIT_COB_ID + node_id,
                                       self.node, self.cam.on_download_refused, self._now)
        self.node._write_callbacks.remove(self.node.nmt.on_write)
        self.network.add_node(self.node)
        self.network.unsubscribe(SDO_RECEIVE_COB_ID + node_id, self.node.sdo.on_request)
        self.network.unsubscribe(NMT_COB_ID, self.node.nmt.on_command)
        self.network.subscribe(SDO_RECEIVE_COB_ID + node_id, self._on_sdo_request)
        self.network.subscribe(NMT_COB_ID, self.nmt.on_command)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        self._reset_application()

    # ------------------------------------------------------------------------ state views
    @property
    def bus(self) -> can.BusABC | None:
        """The drive's bus (None once :meth:`close` released a bus the drive opened)."""
        return self.runner.bus

    @property
    def failure(self) -> BaseException | None:
        """The bus error that stopped the thread of :meth:`start` (None while it serves)."""
        return self.runner.failure

    @property
    def state(self) -> str:
        """The CiA 402 state."""
        return self.state_machine.state

    @property
    def nmt_state(self) -> int:
        """The NMT state code (as the heartbeat sends it)."""
        return self.nmt.state

    @property
    def active_table(self):
        """The cam table the drive runs (None before the first activation)."""
        return self.cam.active_table

    @property
    def pending_table(self):
        """The verified table waiting for activation (None if none)."""
        return self.cam.pending_table

    # ---------------------------------------------------------------------------- clocks
    def _now(self) -> float:
        return time.time() if self._wall_clock else self.time_s

    @property
    def cycle_s(self) -> float:
        """Interpolation time period 0x60C2 [s]: value x 10^index."""
        return self.axis.cycle_s

    # ------------------------------------------------------------------ SDO server hooks
    def _on_read(self, index, subindex, od):
        key = (index, subindex)
        if key in self.values:
            return self.values[key]
        if index == CAM_TABLE_DOWNLOAD.index:
            return self.cam.blob
        return None

    def _on_write(self, index, subindex, od, data):
        """SDO writes (and nothing else): validate, then update the drive."""
        if index == CAM_TABLE_DOWNLOAD.index:
            self.cam.verify_download(bytes(data))
            return
        value = od.decode_raw(data)
        key = (index, subindex)
        if od.data_type in NUMBER_TYPES:
            # Every number within the limits the EDS documents (0x06090031 / 0x06090032), e.g.
            # 0x6076 motor rated torque >= 1: it divides every torque report (0x6077 is per
            # mille of it), and 0x60C2:01 >= 1: the interpolation period divides the velocities.
            check_range(od, value)
        if key in self.values:
            self._set_value(key, value)
        elif index == PRODUCER_HEARTBEAT_TIME.index:
            self.nmt.set_heartbeat_period(value / 1000.0)
        elif index == INTERPOLATION_TIME_PERIOD:
            self._write_interpolation_period(subindex, value)
        elif index in PDO_PARAMETERS:
            check_pdo_write(self.objects, index, subindex, value)
            self.pdo.dirty = True
        elif index == COB_ID_SYNC.index:
            check_cob_id(value, sync=True)
            self.pdo.dirty = True
        elif index == SYNC_COUNTER_OVERFLOW.index:
            self._check_sync_counter_overflow(value)
            self._sync_counting = value != 0
        elif index == COMMUNICATION_CYCLE_PERIOD.index and self._last_sync_wall is not None:
            self._last_sync_wall = time.monotonic()  # a new period: its time-out counts from now

    def _check_sync_counter_overflow(self, value: int) -> None:
        """0x1019 (CiA 301 7.5.2.22): 0 or 2..240 (1 and 241..255 are reserved: abort
        0x06090030), and written only while the communication cycle period 0x1006 is 0 (abort
        0x08000022), as CANopenNode's OD_write_1019 does."""
        if value == 1 or value > 240:
            raise SdoAbortedError(ABORT_INVALID_VALUE)
        if self.objects.stored(COMMUNICATION_CYCLE_PERIOD):
            raise SdoAbortedError(ABORT_DEVICE_STATE)

    def _set_value(self, key, value) -> None:
        """Write a live object and run its side effects."""
        writer = self._writers.get(key)
        if writer is None:
            self.values[key] = value
        else:
            writer(value)

    def _write_interpolation_period(self, subindex: int, value: int) -> None:
        """0x60C2: only with the power stage off; the axis is rebuilt for the new period."""
        if self.state_machine.state in ENERGIZED:
            raise SdoAbortedError(ABORT_DEVICE_STATE)
        period_value = self.objects.stored(INTERPOLATION_TIME_PERIOD_VALUE)
        period_index = self.objects.stored(INTERPOLATION_TIME_INDEX)
        if subindex == INTERPOLATION_TIME_PERIOD_VALUE.subindex:
            period_value = value
        else:
            period_index = value
        period = interpolation_period_s(period_value, period_index)
        if subindex in (INTERPOLATION_TIME_PERIOD_VALUE.subindex,
                        INTERPOLATION_TIME_INDEX.subindex):
            # The period the written part makes with the stored one, within what the control
            # loop runs (CiA 301: value too low / too high).
            if period < MIN_INTERPOLATION_PERIOD_S:
                raise SdoAbortedError(ABORT_VALUE_TOO_LOW)
            if period > MAX_INTERPOLATION_PERIOD_S:
                raise SdoAbortedError(ABORT_VALUE_TOO_HIGH)
            self._make_axis(self.axis.position_counts, period)

    def _on_sdo_request(self, can_id, data, timestamp) -> None:
        if self.nmt.state in (PRE_OPERATIONAL, OPERATIONAL):
            self.node.sdo.on_request(can_id, data, timestamp)
            if self.pdo.dirty:  # a PDO parameter was written: takes effect now
                self.pdo.build()
            self.pdo.send_event_tpdos()

    # ------------------------------------------------------------------------------- NMT
    def boot(self) -> None:
        """Power on: initialise, send the boot-up message, enter PRE-OPERATIONAL."""
        self.nmt.boot()

    def _nmt_entered(self, state: int) -> None:
        self._last_sync_wall = None  # the SYNC supervision starts again with the next SYNC
        if state != OPERATIONAL:
            self.pdo.latched.clear()
        else:
            self.pdo.restart_sync_tpdos()
            self.pdo.send_event_tpdos()

    def _reset(self, kind: str) -> None:
        # CiA 301: a reset node's SDO server starts afresh; a transfer in progress ends with it
        # (its later segments are refused, never spliced onto it).
        self.node.sdo.reset()
        if kind == "application":
            self._reset_application()
        else:
            self._reset_communication()

    def _reset_communication(self) -> None:
        self.objects.forget(COMMUNICATION_AREA)
        heartbeat = self._heartbeat_ms_override
        if heartbeat is not None:
            self.objects.store(PRODUCER_HEARTBEAT_TIME, heartbeat)
        self.nmt.reset_heartbeat(self.objects.stored(PRODUCER_HEARTBEAT_TIME) / 1000.0)
        self._last_sync_wall = None
        self._sync_counting = self.objects.stored(SYNC_COUNTER_OVERFLOW) != 0
        self.pdo.build()

    def _reset_application(self) -> None:
        """Power-on values: the live objects, the 402 state, the cam tables."""
        position = self.axis.position_counts if self.axis is not None else self._initial_counts
        self.objects.forget(APPLICATION_AREA)
        values = self.values
        values.clear()
        values.update((key, self.objects.default(key)) for key in PROCESS_OBJECTS)
        values[CAM_LAST_ERROR_MESSAGE] = NO_ERROR_MESSAGE
        if self.mechanics.motor_torque_limit is not None:
            values[MOTOR_RATED_TORQUE] = min(max(1, round(self.mechanics.motor_torque_limit * 1000.0)),
                                            UNSIGNED32_MAX)
        self.cam.reset()
        self._make_axis(position)
        self._reset_communication()
        self.state_machine.reset(self.axis.position_counts)

    def _on_enable(self) -> None:
        """OPERATION ENABLED entered (not from quick stop): start from the actual position."""
        self.cam.forget_master()
        self.axis.restart()

    def _make_axis(self, position_counts: int, cycle_s: float | None = None) -> None:
        """(Re)build the servo axis at ``position_counts`` for an interpolation period."""
        if cycle_s is None:
            cycle_s = interpolation_period_s(self.objects.stored(INTERPOLATION_TIME_PERIOD_VALUE),
                                             self.objects.stored(INTERPOLATION_TIME_INDEX))
        self.axis = self.axis_setup.build(cycle_s, int(position_counts))
        self.values[POSITION_ACTUAL_VALUE] = wrap_int32(self.axis.position_counts)
        self.values[FOLLOWING_ERROR_ACTUAL_VALUE] = 0

    # ----------------------------------------------------------------------------- cycle
    def _on_sync(self, can_id, data, timestamp) -> None:
        # CiA 301 7.5.2.22 (0x1019): with the counter off the SYNC has no data, with it on one
        # byte, the counter. A SYNC of the other length is not taken as one (CANopenNode's
        # CO_SYNC_receive) and reported once, until a right one comes, with EMCY 0x8240
        # (CiA 301 emergency error codes: unexpected SYNC data length).
        counting = self._sync_counting
        if len(data) != (1 if counting else 0):
            self.sync_length_errors += 1
            if not self._sync_length_reported:
                self._sync_length_reported = True
                self.emcy.send(EMCY_SYNC_DATA_LENGTH, ERROR_REGISTER_COMMUNICATION)
            return
        self._sync_length_reported = False
        if self._wall_clock:
            self._last_sync_wall = time.monotonic()
        self.run_cycle(synchronous=True, counter=data[0] if counting else None)

    def _on_defect(self, what: str) -> None:
        """An exception escaped a handler (logged by the runner): fault with EMCY 0x6100."""
        self.defects += 1
        self.state_machine.fault(EMCY_INTERNAL_SOFTWARE, ERROR_REGISTER_GENERIC)

    def _on_idle(self) -> None:
        self.nmt.service_heartbeat()
        self.node.sdo.service()
        if self._wall_clock:
            self.supervise_sync(time.monotonic())

    def supervise_sync(self, now: float) -> None:
        """React once when the SYNC stops (an external master on the wall clock).

        CiA 301 0x1006 (communication cycle period, us) non-zero arms the supervision from the
        next SYNC: after SYNC_LOSS_PERIODS periods without a SYNC, in NMT OPERATIONAL, the
        connection counts as lost and CiA 402 0x6007 (abort connection option code) picks the
        reaction: 0 none, 1 fault (EMCY 0x8100, CiA 301 "communication, generic", the code
        CANopenNode reports its SYNC time-out with, 301/CO_SYNC.c), 2 disable voltage, 3 quick
        stop. The next SYNC re-arms it, also after an NMT state change; a write of 0x1006
        restarts the time-out. The drive then keeps its own timer for one period, so the
        reaction (a fault reaction ending in FAULT, CiA 402 transitions 13 and 14) takes effect
        without a SYNC. In lock-step (the rig) the master never stops the SYNC, and a dropped
        one runs :meth:`free_run`.
        """
        period_us = self.objects.stored(COMMUNICATION_CYCLE_PERIOD)
        last = self._last_sync_wall
        if not period_us or last is None or self.nmt.state != OPERATIONAL:
            return
        if now - last <= SYNC_LOSS_PERIODS * period_us * 1e-6:
            return
        self._last_sync_wall = None
        self.sync_losses += 1
        option = self.objects.stored(ABORT_CONNECTION_OPTION_CODE)
        machine = self.state_machine
        if machine.state not in ENERGIZED or option == 0:
            return
        if option == 1:
            machine.fault(EMCY_COMMUNICATION, ERROR_REGISTER_COMMUNICATION)
        elif option == 2:
            machine.enter(SWITCH_ON_DISABLED)
        elif option == 3 and machine.state == OPERATION_ENABLED:
            machine.enter(QUICK_STOP_ACTIVE)
        self.free_run()

    def free_run(self) -> None:
        """Run one interpolation period without a SYNC (the SYNC was lost): the control loop
        keeps its own timer, synchronous RPDOs stay latched and no synchronous TPDO is sent."""
        self.run_cycle(synchronous=False)

    def run_cycle(self, synchronous: bool = True, counter: int | None = None) -> None:
        """One interpolation period: latch RPDOs, run the axis, publish, send TPDOs
        (``counter``: the SYNC's counter byte when 0x1019 turns the counter on)."""
        values = self.values
        if synchronous:
            self.pdo.apply_latched()
        state_machine = self.state_machine
        state = state_machine.state
        axis = self.axis
        if state in ENERGIZED:
            if (state == OPERATION_ENABLED
                    and values[MODES_OF_OPERATION_DISPLAY] == CYCLIC_SYNCHRONOUS_POSITION):
                cam = self.cam
                if cam.drives_the_target:
                    target, velocity = cam.target(self.cycle_s)
                    values[TARGET_POSITION] = wrap_int32(target)
                    values[VELOCITY_OFFSET] = saturate_int32(round(velocity))
                else:
                    if cam.active_table is not None:  # a cam to engage: follow the master
                        cam.observe(self.cycle_s)
                    target, velocity = values[TARGET_POSITION], values[VELOCITY_OFFSET]
            elif state == OPERATION_ENABLED:
                target, velocity = values[TARGET_POSITION], 0.0  # no mode: hold the last target
            else:
                target, velocity = state_machine.hold_counts, 0.0
            start = time.perf_counter()
            axis.cycle(target, velocity)
            self.axis_wall_s += time.perf_counter() - start
            plant = axis.plant
            following_error = axis.following_error_counts
            values[POSITION_ACTUAL_VALUE] = wrap_int32(axis.position_counts)
            values[FOLLOWING_ERROR_ACTUAL_VALUE] = wrap_int32(following_error)
            # a velocity that leaves INTEGER32 saturates: a wrap would flip its sign
            values[VELOCITY_ACTUAL_VALUE] = saturate_int32(round(axis.velocity_counts_per_s))
            torque = round(plant.motor_torque * 1e6 / values[MOTOR_RATED_TORQUE])
            values[TORQUE_ACTUAL_VALUE] = min(max(torque, -32768), 32767)
            state_machine.check_following_error(following_error, self.time_s)
            if state == FAULT_REACTION_ACTIVE:
                state_machine.reaction_done()  # CiA 402 transition 14: hold, then off, done
        else:
            # Power stage off: no torque. A spinning load coasts (friction and damping slow it)
            # and the encoder still reads it: 0x6064 and 0x606C report where it goes.
            axis.coast()
            values[POSITION_ACTUAL_VALUE] = wrap_int32(axis.position_counts)
            values[VELOCITY_ACTUAL_VALUE] = saturate_int32(round(axis.velocity_counts_per_s))
            values[FOLLOWING_ERROR_ACTUAL_VALUE] = 0
            values[TORQUE_ACTUAL_VALUE] = 0
        self.cycles += 1
        self.time_s = self.cycles * self.cycle_s
        self.nmt.service_heartbeat()
        self.node.sdo.service()
        if synchronous:
            self.pdo.send_sync_tpdos(counter)
        self.pdo.send_event_tpdos()

    # -------------------------------------------------------------------------- running
    def process(self) -> int:
        """Handle every frame waiting on the bus, in order (lock-step use); return the count."""
        return self.runner.process()

    def start(self) -> None:
        """Boot and handle frames in a thread of its own until :meth:`stop` (external masters)."""
        self.runner.start(self._boot_on_wall_clock)

    def _boot_on_wall_clock(self) -> None:
        # An external master runs on real time: heartbeats and frame stamps follow it, and a
        # large table is verified off the serving thread (CamSlot).
        self._wall_clock = True
        self.cam.background = True
        self.boot()

    def _locked(self, function) -> None:
        with self.runner.lock:
            function()

    def stop(self) -> None:
        """Stop the thread of :meth:`start` and release the bus if the drive opened it."""
        self.runner.stop()

    def close(self) -> None:
        """Release the bus if the drive opened it."""
        self.runner.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
