"""The drive's time and its supervision of the SYNC (issue 13, item 2).

Driven by a master, the drive's simulated time advances one interpolation period (0x60C2) per
SYNC, in lock-step and free-running alike. When the SYNC stops, a free-running drive (an external
master on the wall clock) reacts as a drive configured for it does: CiA 301 0x1006 (communication
cycle period) non-zero arms the supervision, and after 3 periods without a SYNC in NMT OPERATIONAL
CiA 402 0x6007 (abort connection option code) picks the reaction: 0 none, 1 fault with EMCY
0x8100 (CiA 301: communication), 2 disable voltage, 3 quick stop.

The free-running tests use an in-process virtual bus and a canopen master in the test's thread;
every wait is bounded.
"""

from __future__ import annotations

import itertools
import struct
import threading
import time

import canopen
import pytest

import ecam

from hil_sim.bus import open_virtual_bus
from hil_sim.drive import EDS_PATH, VirtualDrive, cia402
from hil_sim.rig import LockstepMaster

NODE = 1
SYNC_PERIOD_S = 0.002
#: The 0x1006 the tests write [us]: ten times the SYNC spacing the master uses, so a scheduling
#: hiccup of a loaded test machine (up to 3 x 20 ms) is not a lost SYNC; a stopped SYNC is
#: then noticed 60 ms after the last one.
SUPERVISED_PERIOD_US = 20_000
EMCY_COMMUNICATION = 0x8100
_channels = itertools.count()


def test_lock_step_time_advances_one_interpolation_period_per_sync():
    channel = f"test-drive-sync-{next(_channels)}"
    drive = VirtualDrive(channel=channel, node_id=NODE)
    master = LockstepMaster(open_virtual_bus(channel), drive)
    node = master.add_node(canopen.RemoteNode(NODE, str(EDS_PATH)))
    try:
        drive.boot()
        master.settle()
        node.sdo[0x60C2][1].raw = 25
        node.sdo[0x60C2][2].raw = -4  # 2.5 ms
        node.nmt.state = "OPERATIONAL"
        for _ in range(40):
            master.sync.transmit()
        assert drive.cycles == 40
        assert drive.time_s == pytest.approx(40 * 0.0025, abs=1e-12)
    finally:
        drive.close()
        master.bus.shutdown()


class FreeRunning:
    """A free-running drive (its own thread, wall clock) and a canopen master on one channel."""

    def __init__(self):
        channel = f"test-drive-sync-{next(_channels)}"
        self.network = canopen.Network()
        self.network.NOTIFIER_CYCLE = 0.05  # its reader thread stops within that on disconnect
        self.network.connect(interface="virtual", channel=channel, receive_own_messages=False)
        self.node = canopen.RemoteNode(NODE, str(EDS_PATH))
        self.network.add_node(self.node)
        self.node.sdo.RESPONSE_TIMEOUT = 2.0
        self.emcys = []
        self.network.subscribe(0x80 + NODE, lambda can_id, data, ts: self.emcys.append(bytes(data)))
        booted = threading.Event()
        self.node.nmt.add_heartbeat_callback(lambda state: booted.set() if state == 0 else None)
        self.drive = VirtualDrive(channel=channel, node_id=NODE)
        self.drive.start()
        assert booted.wait(5.0), "no boot-up message"

    def enable(self, cycle_period_us: int, option: int | None = None) -> None:
        sdo = self.node.sdo
        sdo[0x1006].raw = cycle_period_us
        if option is not None:
            sdo[0x6007].raw = option
        sdo[0x6060].raw = cia402.CYCLIC_SYNCHRONOUS_POSITION
        self.node.nmt.state = "OPERATIONAL"
        for controlword in (0x06, 0x07, 0x0F):
            sdo[0x6040].raw = controlword
        assert self.drive.state == cia402.OPERATION_ENABLED

    def syncs(self, count: int) -> None:
        for _ in range(count):
            self.network.sync.transmit()
            time.sleep(SYNC_PERIOD_S)

    def wait_for(self, predicate, timeout: float = 2.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            time.sleep(0.005)
        return predicate()

    def emcy_codes(self) -> list[int]:
        return [struct.unpack_from("<H", data)[0] for data in self.emcys]

    def close(self) -> None:
        self.drive.stop()
        self.network.disconnect()


@pytest.fixture
def free():
    rig = FreeRunning()
    yield rig
    rig.close()


def test_starting_a_running_drive_is_a_simulation_error(free):
    with pytest.raises(ecam.SimulationError, match="^the drive is already running"):
        free.drive.start()
    assert free.drive.runner.thread.is_alive()  # the running drive is left as it was
    free.node.nmt.state = "OPERATIONAL"
    cycles = free.drive.cycles
    free.syncs(3)
    assert free.wait_for(lambda: free.drive.cycles == cycles + 3)


def test_free_running_time_advances_one_interpolation_period_per_sync(free):
    # An external master: heartbeats follow the wall clock, the control loop the SYNC.
    free.node.sdo[0x60C2][1].raw = 4  # 4 ms, not the SYNC spacing the master happens to use
    free.node.nmt.state = "OPERATIONAL"
    cycles = free.drive.cycles
    free.syncs(25)
    assert free.wait_for(lambda: free.drive.cycles == cycles + 25)
    time.sleep(0.05)
    assert free.drive.cycles == cycles + 25  # no SYNC, no cycle: 0x1006 is 0, nothing supervised
    assert free.drive.time_s == pytest.approx((cycles + 25) * 0.004, abs=1e-12)
    assert free.drive.sync_losses == 0


REACTIONS = [  # 0x6007 -> (state after the SYNC stopped, EMCY 0x8100 sent)
    (0, cia402.OPERATION_ENABLED, False),
    (1, cia402.FAULT, True),
    (2, cia402.SWITCH_ON_DISABLED, False),
    (3, cia402.QUICK_STOP_ACTIVE, False),
]


@pytest.mark.parametrize("option,state,emcy", REACTIONS)
def test_a_lost_sync_gets_the_reaction_0x6007_configures(free, option, state, emcy):
    free.enable(SUPERVISED_PERIOD_US, option)
    free.syncs(20)
    assert free.drive.state == cia402.OPERATION_ENABLED and free.drive.sync_losses == 0
    # the SYNC stops: lost after 3 periods of 0x1006 (60 ms), the reaction follows at once
    assert free.wait_for(lambda: free.drive.sync_losses == 1)
    assert free.wait_for(lambda: free.drive.state == state), free.drive.state
    statusword = free.node.sdo[0x6041].raw
    assert statusword & 0x6F == cia402.STATUSWORD_OF_STATE[state] & 0x6F, hex(statusword)
    if emcy:
        assert free.wait_for(lambda: EMCY_COMMUNICATION in free.emcy_codes())
        assert free.node.sdo[0x603F].raw == EMCY_COMMUNICATION
        assert free.node.sdo[0x1001].raw & 0x10  # error register: communication
    else:
        time.sleep(0.02)
        assert EMCY_COMMUNICATION not in free.emcy_codes()


def test_sync_supervision_re_arms_with_the_next_sync_and_recovers_after_a_fault_reset(free):
    free.enable(SUPERVISED_PERIOD_US)  # 0x6007 default: 1, fault
    assert free.node.sdo[0x6007].raw == 1
    free.syncs(10)
    assert free.wait_for(lambda: free.drive.state == cia402.FAULT)
    free.node.sdo[0x6040].raw = 0x80  # fault reset (CiA 402 transition 15)
    assert free.drive.state == cia402.SWITCH_ON_DISABLED
    assert free.node.sdo[0x603F].raw == 0
    free.syncs(5)  # the master is back: the next SYNC re-arms the supervision
    for controlword in (0x06, 0x07, 0x0F):
        free.node.sdo[0x6040].raw = controlword
    assert free.drive.state == cia402.OPERATION_ENABLED
    free.syncs(10)
    assert free.drive.state == cia402.OPERATION_ENABLED
    assert free.wait_for(lambda: free.drive.sync_losses == 2)
    assert free.wait_for(lambda: free.drive.state == cia402.FAULT)


def test_no_supervision_without_0x1006_or_outside_operational(free):
    free.enable(0)  # 0x1006 = 0: the SYNC is not supervised
    free.syncs(10)
    time.sleep(0.05)
    assert free.drive.state == cia402.OPERATION_ENABLED and free.drive.sync_losses == 0
    free.node.nmt.state = "PRE-OPERATIONAL"  # CiA 301: no PDOs, no SYNC supervision
    free.node.sdo[0x1006].raw = SUPERVISED_PERIOD_US
    free.syncs(10)
    time.sleep(0.1)  # beyond 3 periods of 0x1006
    assert free.drive.sync_losses == 0
    assert free.drive.state == cia402.OPERATION_ENABLED


def test_writing_0x1006_while_the_sync_runs_supervises_it_from_then_on(free):
    # What the cross-process master does: SYNC running, then 0x1006 written, then the SYNC stops.
    free.enable(0)
    free.syncs(10)
    free.node.sdo[0x1006].raw = SUPERVISED_PERIOD_US  # the time-out counts from the write
    assert free.wait_for(lambda: free.drive.sync_losses == 1)
    assert free.wait_for(lambda: free.drive.state == cia402.FAULT)
    assert free.wait_for(lambda: EMCY_COMMUNICATION in free.emcy_codes())
