"""The virtual drive as a CANopen slave: NMT, heartbeat, SDO, PDO, CiA 402, EMCY, and the
drive-side cam download.

Most tests run the drive in lock-step with a canopen ``RemoteNode`` (no threads, simulated
time, exact frames). One test runs canopen's own CiA 402 master, ``BaseNode402``, against the
free-running drive: that master blocks on TPDO receptions, so there the drive serves frames in
a thread and the SYNC producer runs in canopen's; every wait is bounded by a timeout.
"""

from __future__ import annotations

import itertools
import struct
import threading

import canopen
import numpy as np
import pytest
from canopen.profiles.p402 import BaseNode402, State402
from hypothesis import given
from hypothesis import strategies as st

import ecam
from hil_sim import drive as drv
from hil_sim.drive import cia402
from hil_sim.bus import open_virtual_bus
from hil_sim.drive import EDS_PATH, VirtualDrive
from hil_sim.rig import LockstepMaster

from conftest import CAMS

_channels = itertools.count()


class Rig:
    """A drive and a lock-step RemoteNode on a fresh virtual channel."""

    def __init__(self, node_id=1, **drive_options):
        channel = f"test-hil-canopen-{next(_channels)}"
        self.drive = VirtualDrive(channel=channel, node_id=node_id, **drive_options)
        self.master = LockstepMaster(open_virtual_bus(channel), self.drive)
        self.node = self.master.add_node(canopen.RemoteNode(node_id, str(EDS_PATH)))
        self.node.sdo.RESPONSE_TIMEOUT = 0.01  # lock-step: an answer is there at once or never
        self.frames = []  # (can id, data, timestamp) of every frame the master received
        for can_id in [0x80 + node_id, 0x180 + node_id, 0x280 + node_id, 0x580 + node_id,
                       0x700 + node_id]:
            self.master.subscribe(can_id, self._log)

    def _log(self, can_id, data, timestamp):
        self.frames.append((can_id, bytes(data), timestamp))

    def received(self, can_id):
        return [(data, timestamp) for cid, data, timestamp in self.frames if cid == can_id]

    def boot_and_enable(self, start=True):
        self.drive.boot()
        self.master.settle()
        self.node.sdo[0x6060].raw = 8
        if start:
            self.node.nmt.state = "OPERATIONAL"
        for controlword in (0x06, 0x07, 0x0F):
            self.node.sdo[0x6040].raw = controlword
        assert self.drive.state == cia402.OPERATION_ENABLED

    def rpdo(self, number, fmt, *values):
        self.master.send_message(0x100 * (number + 1) + self.node.id, struct.pack(fmt, *values))

    def close(self):
        self.drive.close()
        self.master.bus.shutdown()


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.close()


@pytest.fixture(scope="module")
def tables():
    drrd = ecam.compile_table(ecam.load_cam(CAMS / "combination_drrd.toml"), interp="cubic",
                         points=289, master_counts=36864, slave_counts_per_unit=100000)
    msine = ecam.compile_table(ecam.load_cam(CAMS / "modified_sine.toml"), interp="cubic", points=257,
                          master_counts=65536, slave_counts_per_unit=1000)
    return drrd, msine


# ---------------------------------------------------------------------------------------------
# BaseNode402, the standard master (threads, bounded waits)

@pytest.mark.slow
def test_base_node_402_enables_csp_streams_targets_and_reads_positions():
    channel = f"test-hil-402-{next(_channels)}"
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel, receive_own_messages=False)
    node = BaseNode402(1, str(EDS_PATH))
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    for name in ("TIMEOUT_RESET_FAULT", "TIMEOUT_SWITCH_OP_MODE", "TIMEOUT_SWITCH_STATE_FINAL",
                 "TIMEOUT_SWITCH_STATE_SINGLE", "TIMEOUT_CHECK_TPDO"):
        setattr(node, name, 5.0)  # upper bounds only: each wait ends at the next TPDO
    booted = threading.Event()
    node.nmt.add_heartbeat_callback(lambda state: booted.set() if state == 0 else None)
    drive = VirtualDrive(channel=channel)
    drive.start()
    try:
        assert booted.wait(5.0), "no boot-up message"
        assert node.nmt.state == "PRE-OPERATIONAL"
        node.setup_402_state_machine()  # reads the PDO configuration by SDO
        network.sync.start(0.002)
        node.nmt.state = "OPERATIONAL"
        node.check_statusword()  # waits for the next TPDO1
        assert node.state == "SWITCH ON DISABLED"
        node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
        assert node.op_mode == "CYCLIC SYNCHRONOUS POSITION"
        node.state = "OPERATION ENABLED"
        assert node.state == "OPERATION ENABLED"
        rpdo, tpdo = node.rpdo[2], node.tpdo[1]
        for i in range(1, 101):  # a ramp of 100 targets, one per received TPDO
            rpdo["Target position"].raw = 300 * i
            rpdo.transmit()
            assert tpdo.wait_for_reception(5.0) is not None
        for _ in range(2000):
            if abs(node.tpdo_values[0x6064] - 30000) <= 5:
                break
            assert tpdo.wait_for_reception(5.0) is not None
        assert abs(node.tpdo_values[0x6064] - 30000) <= 5  # counts
        assert node.sdo[0x607A].raw == 30000  # the RPDO was written into the drive's OD
        node.state = "SWITCH ON DISABLED"
        assert node.state == "SWITCH ON DISABLED"
    finally:
        network.sync.stop()
        drive.stop()
        network.disconnect()


# ---------------------------------------------------------------------------------------------
# NMT and heartbeat

def test_boot_up_heartbeat_and_nmt_states_on_simulated_time(rig):
    node_id = rig.node.id
    rig.drive.boot()
    rig.master.settle()
    assert rig.received(0x700 + node_id) == [(b"\x00", 0.0)]  # boot-up at t = 0
    assert rig.node.nmt.state == "PRE-OPERATIONAL"
    rig.node.sdo[0x1017].raw = 10  # ms
    for _ in range(30):
        rig.master.sync.transmit()  # 1 ms each
    beats = rig.received(0x700 + node_id)[1:]
    assert [d for d, _ in beats] == [b"\x7f"] * 3
    assert [round(t, 9) for _, t in beats] == [0.01, 0.02, 0.03]  # s, exact in lock-step
    assert rig.received(0x180 + node_id) == []  # no PDO before OPERATIONAL

    rig.node.nmt.state = "OPERATIONAL"
    for _ in range(10):
        rig.master.sync.transmit()
    assert rig.received(0x700 + node_id)[-1][0] == b"\x05"
    assert len(rig.received(0x180 + node_id)) == 10  # TPDO1 on every SYNC

    rig.node.nmt.state = "STOPPED"
    sent = len(rig.received(0x180 + node_id))
    for _ in range(10):
        rig.master.sync.transmit()
    assert rig.received(0x700 + node_id)[-1][0] == b"\x04"
    assert len(rig.received(0x180 + node_id)) == sent  # no PDO when stopped
    with pytest.raises(canopen.SdoCommunicationError):
        rig.node.sdo[0x6041].raw  # no SDO when stopped

    rig.node.nmt.state = "RESET"  # reset node: boot-up again, power-on values
    assert rig.received(0x700 + node_id)[-1][0] == b"\x00"
    assert rig.node.sdo[0x1017].raw == 1000  # ms, the EDS default again
    assert rig.drive.nmt_state == cia402.PRE_OPERATIONAL


def test_heartbeat_time_can_be_switched_off(rig):
    rig.drive.boot()
    rig.master.settle()
    rig.node.sdo[0x1017].raw = 0
    for _ in range(50):
        rig.master.sync.transmit()
    assert len(rig.received(0x700 + rig.node.id)) == 1  # the boot-up only


# ---------------------------------------------------------------------------------------------
# CiA 402 state machine (the data table), PDOs

PATH = [  # (controlword, state after it): CiA 402 transitions 2, 3, 4, 5, 6, 7, 2, 3+4, 11, 16, 8, 7
    (0x06, cia402.READY_TO_SWITCH_ON), (0x07, cia402.SWITCHED_ON), (0x0F, cia402.OPERATION_ENABLED),
    (0x07, cia402.SWITCHED_ON), (0x06, cia402.READY_TO_SWITCH_ON), (0x00, cia402.SWITCH_ON_DISABLED),
    (0x06, cia402.READY_TO_SWITCH_ON), (0x0F, cia402.OPERATION_ENABLED), (0x02, cia402.QUICK_STOP_ACTIVE),
    (0x0F, cia402.OPERATION_ENABLED), (0x06, cia402.READY_TO_SWITCH_ON), (0x02, cia402.SWITCH_ON_DISABLED),
    (0x0F, cia402.SWITCH_ON_DISABLED),  # no transition from SWITCH ON DISABLED on enable operation
]


def test_power_state_machine_follows_the_controlword(rig):
    rig.drive.boot()
    rig.master.settle()
    assert rig.node.sdo[0x6041].raw & 0x4F == 0x40  # switch on disabled
    for controlword, state in PATH:
        rig.node.sdo[0x6040].raw = controlword
        assert rig.drive.state == state, hex(controlword)
        statusword = rig.node.sdo[0x6041].raw
        assert statusword == cia402.STATUSWORD_OF_STATE[state] | cia402.SW_REMOTE, (hex(controlword), hex(statusword))


@pytest.mark.slow
@given(st.lists(st.sampled_from([0x00, 0x02, 0x06, 0x07, 0x0F, 0x0B, 0x80, 0x8F, 0x86]),
                max_size=12))
def test_statusword_always_decodes_to_the_drive_state_for_base_node_402(controlwords):
    rig = Rig()
    try:
        rig.drive.boot()
        rig.master.settle()
        for controlword in controlwords:
            rig.node.sdo[0x6040].raw = controlword
            statusword = rig.node.sdo[0x6041].raw
            decoded = [name for name, (mask, bits) in State402.SW_MASK.items()
                       if statusword & mask == bits]
            assert decoded == [rig.drive.state], (hex(controlword), hex(statusword))
            assert statusword & cia402.SW_REMOTE
    finally:
        rig.close()


def test_modes_of_operation_and_supported_modes(rig):
    rig.drive.boot()
    rig.master.settle()
    assert rig.node.sdo[0x6502].raw == 0x80  # CSP only
    rig.node.sdo[0x6060].raw = 8
    assert rig.node.sdo[0x6061].raw == 8
    with pytest.raises(canopen.SdoAbortedError) as error:
        rig.node.sdo[0x6060].raw = 1  # profile position: not supported
    assert error.value.code == drv.ABORT_INVALID_VALUE
    assert rig.node.sdo[0x6061].raw == 8


def test_rpdo_values_land_in_the_object_dictionary_at_the_sync(rig):
    rig.boot_and_enable()
    start = rig.node.sdo[0x6064].raw
    rig.rpdo(2, "<ii", start + 1000, 0)  # target position, velocity offset (synchronous RPDO)
    assert rig.node.sdo[0x607A].raw == start  # latched, not applied before the SYNC
    rig.master.sync.transmit()
    assert rig.node.sdo[0x607A].raw == start + 1000
    statusword, mode, position = struct.unpack("<HbI", rig.received(0x181)[-1][0])
    assert statusword & 0x6F == 0x27 and mode == 8
    following_error, torque = struct.unpack("<ih", rig.received(0x281)[-1][0])
    assert following_error == start + 1000 - position


def test_pdo_mapping_is_validated_and_rebuilt(rig):
    rig.drive.boot()
    rig.master.settle()
    sdo = rig.node.sdo
    sdo[0x1A01][0].raw = 0
    sdo[0x1A01][1].raw = 0x60410010  # statusword into TPDO2
    with pytest.raises(canopen.SdoAbortedError) as error:
        sdo[0x1A01][2].raw = 0x60650020  # following error window: not mappable
        sdo[0x1A01][0].raw = 2
    assert error.value.code == drv.ABORT_CANNOT_MAP
    sdo[0x1A01][0].raw = 1
    rig.node.nmt.state = "OPERATIONAL"
    rig.master.sync.transmit()
    assert len(rig.received(0x281)[-1][0]) == 2  # bytes: the new mapping


# ---------------------------------------------------------------------------------------------
# Following error fault and EMCY

def test_following_error_raises_a_fault_with_emcy_and_resets(rig):
    rig.boot_and_enable()
    rig.node.sdo[0x6065].raw = 50  # counts
    start = rig.node.sdo[0x6064].raw
    rig.rpdo(2, "<ii", start + 5000, 0)  # a jump the axis cannot follow within 50 counts
    rig.master.sync.transmit()
    assert rig.drive.state in (cia402.FAULT_REACTION_ACTIVE, cia402.FAULT)
    rig.master.sync.transmit()
    assert rig.drive.state == cia402.FAULT
    statusword = rig.node.sdo[0x6041].raw
    assert statusword & 0x4F == 0x08  # fault
    assert rig.node.sdo[0x603F].raw == 0x8611
    assert rig.node.sdo[0x1001].raw & 0x01
    emcy = rig.received(0x81)
    assert len(emcy) == 1
    code, register, _ = struct.unpack("<HB5s", emcy[0][0])
    assert code == 0x8611 and register & 0x01
    assert [e.code for e in rig.node.emcy.active] == [0x8611]

    rig.node.sdo[0x6040].raw = 0x00
    rig.node.sdo[0x6040].raw = 0x80  # fault reset: rising edge of bit 7
    assert rig.drive.state == cia402.SWITCH_ON_DISABLED
    assert rig.node.sdo[0x603F].raw == 0
    assert rig.node.emcy.active == []  # the EMCY 0x0000 (error reset) was received
    assert struct.unpack("<H", rig.received(0x81)[-1][0][:2])[0] == 0


def test_following_error_time_out_delays_the_fault_and_sets_bit_13(rig):
    rig.boot_and_enable()
    rig.node.sdo[0x6065].raw = 50  # counts
    rig.node.sdo[0x6066].raw = 5  # ms
    start = rig.node.sdo[0x6064].raw
    rig.rpdo(2, "<ii", start + 100000, 0)
    rig.master.sync.transmit()
    assert rig.drive.state == cia402.OPERATION_ENABLED
    assert rig.node.sdo[0x6041].raw & cia402.SW_FOLLOWING_ERROR
    for _ in range(6):
        rig.master.sync.transmit()
    assert rig.drive.state == cia402.FAULT


# ---------------------------------------------------------------------------------------------
# Drive-side cam: download, verify, activate; refuse bad downloads

def cam_targets(rig, masters):
    """Stream master positions (RPDO3) and return the drive's targets 0x607A after each SYNC."""
    out = []
    for master in masters:
        rig.rpdo(3, "<i", int(master))
        rig.master.sync.transmit()
        out.append(rig.drive.values[(0x607A, 0)])
    return out


def start_cam(rig, table):
    rig.boot_and_enable()
    sdo = rig.node.sdo
    sdo.download(0x2000, 0, table.to_bytes())
    assert sdo[0x2005].raw == table.crc32  # pending, verified
    assert sdo[0x2001][2].raw == drv.CAM_STATUS_PENDING
    sdo[0x2001][1].raw = drv.CAM_COMMAND_ACTIVATE
    assert sdo[0x2002].raw == table.crc32
    assert sdo[0x2001][2].raw == drv.CAM_STATUS_ACTIVE
    sdo[0x2004].raw = 1


def test_good_blob_activates_and_the_drive_runs_the_cam(rig, tables):
    drrd, _ = tables
    start_cam(rig, drrd)
    masters = np.arange(1, 200) * 50  # master counts
    targets = cam_targets(rig, masters)
    assert targets == [int(v) for v in drrd.lookup(masters)]  # bit-exact with the table


def test_cam_mode_needs_an_active_table(rig):
    rig.boot_and_enable()
    with pytest.raises(canopen.SdoAbortedError) as error:
        rig.node.sdo[0x2004].raw = 1
    assert error.value.code == drv.ABORT_DEVICE_STATE
    with pytest.raises(canopen.SdoAbortedError):
        rig.node.sdo[0x2001][1].raw = drv.CAM_COMMAND_ACTIVATE  # nothing pending


def raw_sdo(rig, frames):
    """Send raw SDO request frames; return the server's responses (bytes)."""
    before = len(rig.received(0x581))
    for frame in frames:
        rig.master.send_message(0x601, frame)
    return [data for data, _ in rig.received(0x581)[before:]]


def segments(blob, stop_after=None, last_early=False):
    """Segmented-download frames (CiA 301) of ``blob``; optionally stop or end early."""
    chunks = [blob[i:i + 7] for i in range(0, len(blob), 7)]
    if stop_after is not None:
        chunks = chunks[:stop_after]
    out = []
    for i, chunk in enumerate(chunks):
        last = i == len(chunks) - 1 and (stop_after is None or last_early)
        command = ((i & 1) << 4) | ((7 - len(chunk)) << 1) | int(last)
        out.append(bytes([command]) + chunk.ljust(7, b"\0"))
    return out


@pytest.mark.parametrize("damage", ["corrupted", "truncated", "aborted", "short_transfer",
                                    "wrong_magic"])
def test_bad_downloads_are_refused_and_the_running_table_keeps_running(rig, tables, damage):
    drrd, msine = tables
    start_cam(rig, drrd)
    masters = np.arange(1, 60) * 100
    before = cam_targets(rig, masters[:30])
    blob = bytearray(msine.to_bytes())
    sdo = rig.node.sdo
    if damage in ("corrupted", "truncated", "wrong_magic"):
        if damage == "corrupted":
            blob[200] ^= 0x04  # one bit of the payload
        elif damage == "truncated":
            blob = blob[:-10]
        else:
            blob[0:4] = b"MACE"
        with pytest.raises(canopen.SdoAbortedError) as error:
            sdo.download(0x2000, 0, bytes(blob))
        assert error.value.code == drv.ABORT_CANNOT_STORE
        message = sdo[0x2001][4].raw
        assert {"corrupted": "payload_crc32", "truncated": "length",
                "wrong_magic": "magic"}[damage] in message
    else:
        initiate = struct.pack("<BHBI", 0x21, 0x2000, 0, len(blob))
        if damage == "aborted":
            abort = struct.pack("<BHBI", 0x80, 0x2000, 0, 0x05040000)
            responses = raw_sdo(rig, [initiate] + segments(bytes(blob), stop_after=20) + [abort])
            assert len(responses) == 21  # the server answered the initiate and each segment
            assert sdo[0x2001][3].raw == 0x05040000  # the client's abort code is recorded
        else:  # the client ends the transfer before the indicated size
            responses = raw_sdo(rig, [initiate] + segments(bytes(blob), stop_after=20,
                                                           last_early=True))
            code = struct.unpack_from("<I", responses[-1], 4)[0]
            assert responses[-1][0] == 0x80 and code == 0x06070010
            assert sdo[0x2001][3].raw == 0x06070010
    assert sdo[0x2001][2].raw & drv.CAM_STATUS_LAST_DOWNLOAD_REFUSED
    assert not sdo[0x2001][2].raw & drv.CAM_STATUS_PENDING
    assert rig.drive.pending_table is None
    assert sdo[0x2002].raw == drrd.crc32  # the running table did not change
    after = cam_targets(rig, masters[30:])
    assert before + after == [int(v) for v in drrd.lookup(masters)]
    # and a good download still goes through afterwards
    sdo.download(0x2000, 0, msine.to_bytes())
    assert sdo[0x2005].raw == msine.crc32
    sdo[0x2001][1].raw = drv.CAM_COMMAND_ACTIVATE
    assert sdo[0x2002].raw == msine.crc32


def test_master_position_wraps_past_int32_without_a_jump(rig, tables):
    drrd, _ = tables
    start_cam(rig, drrd)
    start = 2**31 - 2000
    masters = [start + 37 * i for i in range(120)]  # crosses 2^31: the INT32 on the wire wraps
    wire = [(m + 2**31) % 2**32 - 2**31 for m in masters]
    assert min(wire) < 0 < max(wire)
    targets = cam_targets(rig, wire)
    assert targets == [int(v) for v in drrd.lookup(np.array(masters, dtype=np.int64))]


# ---------------------------------------------------------------------------------------------
# The `hil-sim drive` command, driven by an ordinary canopen master

@pytest.mark.slow
@pytest.mark.parametrize("scene", [None, "drive_side.toml"])
def test_drive_command_serves_a_canopen_master_until_stopped(scene):
    import argparse
    from pathlib import Path

    from ecam.app.cli import add_drive_arguments
    from ecam.app.drive_command import drive_command

    channel = f"test-hil-cli-{next(_channels)}"
    parser = argparse.ArgumentParser()
    add_drive_arguments(parser)
    argv = ["--interface", "virtual", "--channel", channel, "--node-id", "5"]
    if scene:
        argv += ["--scene", str(Path(__file__).resolve().parent.parent / "hil_sim" / "scenes" / scene)]
    args = parser.parse_args(argv)
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel, receive_own_messages=False)
    node = network.add_node(5, str(EDS_PATH))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    booted = threading.Event()
    node.nmt.add_heartbeat_callback(lambda state: booted.set() if state == 0 else None)
    stop = threading.Event()
    result = []
    worker = threading.Thread(target=lambda: result.append(drive_command(args, stop)))
    worker.start()
    try:
        assert booted.wait(5.0)
        assert node.sdo[0x1000].raw == 0x00020192  # device type: CiA 402 servo drive
        assert node.sdo[0x6041].raw & 0x4F == 0x40
    finally:
        stop.set()
        worker.join(10.0)
        network.disconnect()
    assert result == [0]


def test_master_that_reverses_jitters_and_stops_inside_a_segment(rig, tables):
    """Hard case: on the drive-side cam a master that runs forward into the C1 rise piece,
    reverses, jitters and stops there gets the table's exact targets at every cycle, with no
    fault, no jump and a finite velocity offset."""
    drrd, _ = tables
    start_cam(rig, drrd)
    inside = int(drrd.master_counts * 75 / 360)  # inside the C1 piece of the rise
    rng = np.random.default_rng(11)
    masters = np.concatenate([
        np.arange(inside - 4000, inside + 1, 40),      # forward into the segment
        np.arange(inside, inside - 2000, -40),         # reverse
        inside - 2000 + rng.integers(-3, 4, 100),      # jitter
        np.full(100, inside - 2000),                   # stop
    ])
    targets = cam_targets(rig, masters)
    assert targets == [int(v) for v in drrd.lookup(masters.astype(np.int64))]
    assert rig.drive.state == cia402.OPERATION_ENABLED
    following = rig.drive.values[(0x60F4, 0)]
    assert abs(following) <= rig.drive.values[(0x6065, 0)]


def test_motor_rated_torque_zero_is_refused_and_the_drive_keeps_running(rig):
    # 0x6076 = 0 was accepted, then every SYNC divided by it (issue 14, item 11). The EDS gives
    # it LowLimit 1: CiA 301 abort 0x06090032, value too low.
    rig.boot_and_enable()
    before = rig.node.sdo[0x6076].raw
    with pytest.raises(canopen.SdoAbortedError) as error:
        rig.node.sdo[0x6076].raw = 0
    assert error.value.code == drv.ABORT_VALUE_TOO_LOW
    assert rig.node.sdo[0x6076].raw == before
    rig.master.sync.transmit()
    rig.master.settle()
    assert rig.node.sdo[0x6041].raw & 0x6F == 0x27  # still operation enabled


@pytest.mark.parametrize("value,expected", [
    (0, 0), (2**31 - 1, 2**31 - 1), (2**31, 2**31 - 1), (-(2**31), -(2**31)),
    (-(2**31) - 1, -(2**31)), (-9_900_000_000_000, -(2**31)),
])
def test_velocity_offset_saturates_at_integer32(value, expected):
    # 0x60B1 is INTEGER32: a velocity beyond it saturates; wrapping would reverse its sign.
    assert drv.saturate_int32(value) == expected


@given(st.lists(st.integers(-(2**62), 2**62), min_size=1, max_size=20))
def test_one_integer32_wrap_and_saturation_for_scalars_and_arrays(values):
    """hil_sim.int32 serves the drive (scalars), the rig's set points (arrays) and the
    controller: the two forms agree element by element, and a wrapped position is congruent to
    the original modulo 2^32 within INTEGER32."""
    from hil_sim import int32

    assert drv.wrap_int32 is int32.wrap_int32 and drv.saturate_int32 is int32.saturate_int32
    wrapped = int32.wrap_int32_array(np.array(values, dtype=np.int64))
    saturated = int32.saturate_int32_array(np.array(values, dtype=np.int64))
    assert wrapped.dtype == saturated.dtype == np.int64
    assert wrapped.tolist() == [int32.wrap_int32(v) for v in values]
    assert saturated.tolist() == [int32.saturate_int32(v) for v in values]
    for v, w, s in zip(values, wrapped.tolist(), saturated.tolist()):
        assert -(2**31) <= w < 2**31 and (v - w) % 2**32 == 0
        assert s == min(max(v, -(2**31)), 2**31 - 1)
    # the velocities the rig streams are rounded floats: clamped before the cast, even past int64
    floats = int32.saturate_int32_array(np.array([1e30, -1e30, 2.0**31, -(2.0**31) - 1, 3.0]))
    assert floats.tolist() == [2**31 - 1, -(2**31), 2**31 - 1, -(2**31), 3]
    assert int32.wrap_int32(2**31) == -(2**31) and int32.wrap_int32(-(2**31) - 1) == 2**31 - 1


def test_re_enabling_after_a_fault_reset_starts_from_the_actual_position(rig):
    # The axis kept the target that caused the fault and interpolated from it again: re-enabling
    # re-faulted at once (issue 10, item 5). CiA 402: OPERATION ENABLED starts where the motor is.
    rig.boot_and_enable()
    start = rig.node.sdo[0x6064].raw
    rig.node.sdo[0x607A].raw = start + 2**29  # far outside the following-error window
    for _ in range(200):
        rig.master.sync.transmit()
        if rig.drive.state == cia402.FAULT:
            break
    assert rig.drive.state == cia402.FAULT
    rig.node.sdo[0x6040].raw = 0x80  # fault reset (rising edge)
    for controlword in (0x06, 0x07, 0x0F):
        rig.node.sdo[0x6040].raw = controlword
    actual = rig.node.sdo[0x6064].raw
    for k in range(100):
        rig.node.sdo[0x607A].raw = actual + 10 * k
        rig.master.sync.transmit()
        assert rig.drive.state == cia402.OPERATION_ENABLED, k
    assert abs(rig.node.sdo[0x60F4].raw) < 1000
