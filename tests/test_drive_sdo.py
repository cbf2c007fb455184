"""The virtual drive's SDO server against hostile frames (issue 14, item 13): every malformed,
stray or garbled request gets the CiA 301 abort naming the right object (never an earlier
transfer's), no exception leaves a handler, a stalled transfer times out, and every written
number is checked against the limits of the EDS. Ends with a bounded, seeded fuzz of the server.

The drive runs in lock-step with a canopen master on an in-process virtual bus (no threads,
simulated time); raw frames go to the SDO request COB-ID and the answers are read back from the
response COB-ID.
"""

from __future__ import annotations

import itertools
import logging
import random
import struct
import time

import canopen
import pytest

import ecam
from hil_sim import drive as drv
from hil_sim.bus import open_virtual_bus
from hil_sim.drive import EDS_PATH, VirtualDrive, cia402
from hil_sim.rig import LockstepMaster

from conftest import CAMS

NODE = 1
REQUEST, RESPONSE = 0x600 + NODE, 0x580 + NODE
_channels = itertools.count()


class Harness:
    """A drive and a lock-step master; raw SDO frames in, the drive's answers out."""

    def __init__(self):
        channel = f"test-drive-sdo-{next(_channels)}"
        self.drive = VirtualDrive(channel=channel, node_id=NODE)
        self.master = LockstepMaster(open_virtual_bus(channel), self.drive)
        self.node = self.master.add_node(canopen.RemoteNode(NODE, str(EDS_PATH)))
        self.node.sdo.RESPONSE_TIMEOUT = 0.01  # lock-step: an answer is there at once or never
        self.answers = []
        self.master.subscribe(RESPONSE, lambda can_id, data, ts: self.answers.append(bytes(data)))
        self.drive.boot()
        self.master.settle()

    def send(self, frame: bytes) -> list[bytes]:
        """One raw request; the SDO frames the drive answered it with."""
        before = len(self.answers)
        self.master.send_message(REQUEST, bytes(frame))
        return self.answers[before:]

    def sync(self, count: int = 1) -> list[bytes]:
        before = len(self.answers)
        for _ in range(count):
            self.master.sync.transmit()
        return self.answers[before:]

    def close(self):
        self.drive.close()
        self.master.bus.shutdown()


@pytest.fixture
def sdo():
    harness = Harness()
    yield harness
    harness.close()


@pytest.fixture(scope="module")
def table():
    return ecam.compile_table(ecam.load_cam(CAMS / "combination_drrd.toml"), interp="cubic",
                              points=289, master_counts=36864, slave_counts_per_unit=100000)


def abort_of(frames: list[bytes]) -> tuple[int, int, int]:
    """(abort code, index, sub-index) of the one answer, which must be an abort."""
    assert len(frames) == 1, frames
    command, index, subindex, code = struct.unpack("<BHBI", frames[0])
    assert command == 0x80, frames[0].hex(" ")
    return code, index, subindex


def upload(index, subindex=0):
    return struct.pack("<BHB4x", 0x40, index, subindex)


def expedited(index, subindex, data: bytes):
    return struct.pack("<BHB", 0x23 | ((4 - len(data)) << 2), index, subindex) + data.ljust(4, b"\0")


# ---------------------------------------------------------------------------------------------
# Malformed frames: the right abort, the right object

MALFORMED = [
    # (what, frame, abort code, index, sub-index) -- a read of 0x6041 precedes each, so a stale
    # object would show as 6041:00.
    ("zero-length frame", b"", drv.ABORT_COMMAND_SPECIFIER, 0, 0),
    ("upload request cut after one byte of the index", b"\x40\x46",
     0x06020000, 0, 0),
    ("upload request without its sub-index", b"\x40\x41\x60", 0x06090011, 0x6041, 0),
    ("upload segment with no upload in progress", b"\x60", drv.ABORT_COMMAND_SPECIFIER, 0, 0),
    ("upload segment (8 bytes) with no upload", b"\x60" + bytes(7), drv.ABORT_COMMAND_SPECIFIER, 0, 0),
    ("download segment with no download", b"\x00" + bytes(7), drv.ABORT_COMMAND_SPECIFIER, 0, 0),
    ("command specifier 7", b"\xe0\x41\x60\x00" + bytes(4), drv.ABORT_COMMAND_SPECIFIER, 0, 0),
    ("block upload initiate (not supported)", b"\xa0\x00\x20\x00\x7f\x00\x00\x00",
     drv.ABORT_COMMAND_SPECIFIER, 0x2000, 0),
    ("block download initiate (not supported)", b"\xc6\x00\x20\x00\x10\x00\x00\x00",
     drv.ABORT_COMMAND_SPECIFIER, 0x2000, 0),
    ("block download end (no block transfer)", b"\xc1" + bytes(7), drv.ABORT_COMMAND_SPECIFIER, 0, 0),
    ("expedited download announcing 4 bytes, carrying 1", b"\x23\x40\x60\x00\x06",
     drv.ABORT_COMMAND_SPECIFIER, 0x6040, 0),
    ("segmented download initiate without its size", b"\x21\x00\x20\x00",
     drv.ABORT_COMMAND_SPECIFIER, 0x2000, 0),
    ("4 bytes into a 2-byte controlword", expedited(0x6040, 0, b"\x06\x00\x00\x00"),
     0x06070012, 0x6040, 0),
    ("1 byte into a 4-byte window", expedited(0x6065, 0, b"\x01"), 0x06070013, 0x6065, 0),
    ("segmented download of 5 bytes into a 4-byte object", b"\x21\x65\x60\x00\x05\x00\x00\x00",
     0x06070012, 0x6065, 0),
    ("object that does not exist", upload(0x5000), 0x06020000, 0x5000, 0),
    ("sub-index 5 of a plain variable", upload(0x6040, 5), 0x06090011, 0x6040, 5),
    ("sub-index 9 of a record", upload(0x60C2, 9), 0x06090011, 0x60C2, 9),
    ("write to a read-only object", expedited(0x6041, 0, b"\x00\x00"), 0x06010002, 0x6041, 0),
    ("upload of an empty cam slot", upload(0x2000), 0x08000024, 0x2000, 0),
]


@pytest.mark.parametrize("what,frame,code,index,subindex", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_frames_get_the_right_abort_naming_the_right_object(sdo, what, frame, code, index,
                                                                      subindex):
    assert sdo.node.sdo[0x6041].raw & 0x4F == 0x40  # a good transfer of 6041:00 just before
    assert abort_of(sdo.send(frame)) == (code, index, subindex), what
    assert sdo.node.sdo[0x1000].raw == 0x00020192  # and the server serves on


def test_an_abort_from_the_client_is_never_answered(sdo):
    assert sdo.send(b"\x80\x00\x20\x00\x00\x00\x04\x05") == []  # nothing in progress
    assert sdo.send(b"\x80") == []  # even a short one
    assert sdo.send(b"\x21\x00\x20\x00\x0e\x00\x00\x00") == [b"\x60\x00\x20\x00" + bytes(4)]
    assert sdo.send(b"\x80\x00\x20\x00\x00\x00\x04\x05") == []  # ends the download
    assert sdo.node.sdo[0x2001][3].raw == 0x05040000  # and the cam records why
    assert abort_of(sdo.send(b"\x00" + bytes(7)))[0] == drv.ABORT_COMMAND_SPECIFIER


def test_toggle_bit_not_alternated_in_a_download(sdo):
    assert sdo.send(b"\x21\x00\x20\x00\x0e\x00\x00\x00") == [b"\x60\x00\x20\x00" + bytes(4)]
    assert sdo.send(b"\x00" + bytes(7)) == [b"\x20" + bytes(7)]  # toggle 0
    assert abort_of(sdo.send(b"\x00" + bytes(7))) == (drv.ABORT_TOGGLE, 0x2000, 0)  # 0 again
    assert sdo.drive.node.sdo.transfer == "idle"
    assert sdo.node.sdo[0x2001][3].raw == drv.ABORT_TOGGLE
    assert "toggle" in sdo.node.sdo[0x2001][4].raw
    assert sdo.node.sdo[0x2001][2].raw & drv.CAM_STATUS_LAST_DOWNLOAD_REFUSED


def test_toggle_bit_not_alternated_in_an_upload(sdo):
    answer = sdo.send(upload(0x2001, 4))  # "no error": 8 bytes, a segmented upload
    assert answer == [b"\x41\x01\x20\x04\x08\x00\x00\x00"]
    assert sdo.send(b"\x60" + bytes(7)) == [b"\x00no erro"]
    assert abort_of(sdo.send(b"\x60" + bytes(7))) == (drv.ABORT_TOGGLE, 0x2001, 4)
    assert sdo.node.sdo[0x2001][4].raw == "no error"  # a whole upload still works


def test_a_new_request_during_a_transfer_ends_it_with_an_abort_naming_it(sdo):
    sdo.send(upload(0x2001, 4))
    assert abort_of(sdo.send(upload(0x6041))) == (drv.ABORT_COMMAND_SPECIFIER, 0x2001, 4)
    assert sdo.drive.node.sdo.transfer == "idle"
    assert sdo.node.sdo[0x6041].raw & 0x4F == 0x40
    sdo.send(b"\x21\x00\x20\x00\x0e\x00\x00\x00")
    assert abort_of(sdo.send(b"")) == (drv.ABORT_COMMAND_SPECIFIER, 0x2000, 0)  # empty frame


def test_segment_shorter_than_its_size_field_and_download_longer_than_indicated(sdo):
    sdo.send(b"\x21\x00\x20\x00\x0e\x00\x00\x00")
    assert abort_of(sdo.send(b"\x00\x01\x02")) == (drv.ABORT_COMMAND_SPECIFIER, 0x2000, 0)
    sdo.send(b"\x21\x00\x20\x00\x08\x00\x00\x00")  # 8 bytes indicated
    sdo.send(b"\x00" + bytes(7))
    assert abort_of(sdo.send(b"\x10" + bytes(7))) == (0x06070012, 0x2000, 0)  # 14 sent
    assert sdo.node.sdo[0x2001][3].raw == 0x06070012


def test_a_stalled_segmented_transfer_times_out_on_the_drive_clock(sdo):
    # CiA 301 abort 0x05040000 after drv.SDO_TIMEOUT_S without a segment (simulated time: the
    # SYNCs of the lock-step master advance it one interpolation period each).
    sdo.node.nmt.state = "OPERATIONAL"
    sdo.send(b"\x21\x00\x20\x00\x0e\x00\x00\x00")
    cycles = round(drv.SDO_TIMEOUT_S / sdo.drive.cycle_s)
    assert sdo.sync(cycles - 1) == []
    answers = sdo.sync(3)
    assert abort_of(answers) == (drv.ABORT_TIMEOUT, 0x2000, 0)
    assert sdo.node.sdo[0x2001][3].raw == drv.ABORT_TIMEOUT
    assert abort_of(sdo.send(b"\x00" + bytes(7)))[0] == drv.ABORT_COMMAND_SPECIFIER  # over
    sdo.send(upload(0x2001, 4))
    assert abort_of(sdo.sync(cycles + 2)) == (drv.ABORT_TIMEOUT, 0x2001, 4)  # an upload too


def test_a_free_running_drive_times_out_a_stalled_transfer_on_the_wall_clock():
    channel = f"test-drive-sdo-{next(_channels)}"
    drive = VirtualDrive(channel=channel, node_id=NODE)
    bus = open_virtual_bus(channel)
    drive.node.sdo.timeout_s = 0.05
    drive.start()
    try:
        while (msg := bus.recv(1.0)) is not None and msg.arbitration_id != 0x700 + NODE:
            pass
        bus.send(canopen_frame(b"\x21\x00\x20\x00\x0e\x00\x00\x00"))
        answers = []
        deadline = time.monotonic() + 5.0
        while len(answers) < 2 and time.monotonic() < deadline:
            msg = bus.recv(0.1)
            if msg is not None and msg.arbitration_id == RESPONSE:
                answers.append(bytes(msg.data))
        assert answers[0][0] == 0x60
        assert abort_of(answers[1:]) == (drv.ABORT_TIMEOUT, 0x2000, 0)
    finally:
        drive.stop()
        bus.shutdown()


def canopen_frame(data: bytes):
    import can
    return can.Message(arbitration_id=REQUEST, data=data, is_extended_id=False)


# ---------------------------------------------------------------------------------------------
# Every written number within the EDS limits

RANGES = [
    # (index, sub-index, value, abort): out of range, so refused and the object unchanged
    (0x6076, 0, 0, drv.ABORT_VALUE_TOO_LOW),  # motor rated torque divides the torque reports
    (0x60C2, 1, 0, drv.ABORT_VALUE_TOO_LOW),  # interpolation period 0
    (0x60C2, 2, -8, drv.ABORT_VALUE_TOO_LOW),
    (0x60C2, 2, 1, drv.ABORT_VALUE_TOO_HIGH),
    (0x6007, 0, 4, drv.ABORT_VALUE_TOO_HIGH),  # abort connection option code 0..3
    (0x6007, 0, -1, drv.ABORT_VALUE_TOO_LOW),
    (0x2001, 1, 6, drv.ABORT_VALUE_TOO_HIGH),  # cam command 0..5 (3: period end, 4: master position, 5: cam-out)
    (0x6084, 0, 0, drv.ABORT_VALUE_TOO_LOW),  # profile deceleration 0: the stop would never end
    (0x60A4, 1, 0, drv.ABORT_VALUE_TOO_LOW),  # profile jerk 0
    (0x2001, 5, 4, drv.ABORT_VALUE_TOO_HIGH),  # switch coordinates: two bits
    (0x2001, 9, 0, drv.ABORT_VALUE_TOO_LOW),  # a master scaling numerator of 0 (issue 23)
    (0x2001, 12, 0, drv.ABORT_VALUE_TOO_LOW),  # a slave scaling denominator of 0: divides
    (0x2004, 0, 2, drv.ABORT_VALUE_TOO_HIGH),  # cam mode 0..1
    (0x1005, 0, 0x40000080, drv.ABORT_INVALID_VALUE),  # SYNC producer: the drive consumes it
    (0x1005, 0, 0x20000080, drv.ABORT_INVALID_VALUE),  # 29-bit CAN-ID
    (0x1005, 0, 0x00000701, drv.ABORT_INVALID_VALUE),  # a heartbeat CAN-ID
    (0x1400, 1, 0x00000601, drv.ABORT_INVALID_VALUE),  # an RPDO on the SDO request CAN-ID
    (0x1800, 1, 0x12345678, drv.ABORT_INVALID_VALUE),  # bits 11..28 set
    (0x1800, 2, 245, drv.ABORT_INVALID_VALUE),  # reserved transmission type
    (0x1401, 2, 252, drv.ABORT_INVALID_VALUE),  # RTR only: the drive answers no remote frame
    (0x6060, 0, 1, drv.ABORT_INVALID_VALUE),  # profile position: not supported
]


@pytest.mark.parametrize("index,subindex,value,code", RANGES,
                         ids=[f"{r[0]:04X}:{r[1]:02X}={r[2]}" for r in RANGES])
def test_written_values_out_of_range_are_refused(sdo, index, subindex, value, code):
    entry = sdo.node.sdo[index]
    variable = entry if isinstance(entry.od, canopen.objectdictionary.ODVariable) else entry[subindex]
    before = variable.raw
    with pytest.raises(canopen.SdoAbortedError) as error:
        variable.raw = value
    assert error.value.code == code
    assert variable.raw == before


def test_the_interpolation_period_is_refused_outside_10_us_to_1_s(sdo):
    period = sdo.node.sdo[0x60C2]
    with pytest.raises(canopen.SdoAbortedError) as error:
        period[2].raw = -7  # 1 x 10^-7 s
    assert error.value.code == drv.ABORT_VALUE_TOO_LOW
    period[2].raw = 0  # 1 s
    with pytest.raises(canopen.SdoAbortedError) as error:
        period[1].raw = 2  # 2 s
    assert error.value.code == drv.ABORT_VALUE_TOO_HIGH
    period[1].raw = 1
    period[2].raw = -5
    period[1].raw = 1  # 10 us: the smallest the drive runs
    assert sdo.drive.cycle_s == pytest.approx(1e-5)


def test_the_0x60C2_encoding_round_trips():
    """The rig's encoder and the drive's decoder of 0x60C2 (value x 10^index s) invert each
    other: every (value 1..255, index -6..0) decodes to a period that encodes to the finest
    index that holds it, which decodes to the same float."""
    from hil_sim.drive.objects import interpolation_period, interpolation_period_s

    for index in range(-6, 1):
        for value in range(1, 256):
            period = interpolation_period_s(value, index)
            encoded = interpolation_period(period)
            assert encoded is not None, (value, index)
            again, finest = encoded
            assert interpolation_period_s(again, finest) == period, (value, index, encoded)
            assert again * 10.0**finest == pytest.approx(value * 10.0**index, rel=1e-12)
            assert 1 <= again <= 255 and (finest == -6 or 10 * again > 255), (value, index, encoded)
    assert interpolation_period(1e-3) == (100, -5)
    assert interpolation_period(0.25) == (250, -3)
    assert interpolation_period(1 / 3000) is None  # 333.3... us has no decimal form
    assert interpolation_period(256.0) is None  # past 255 x 10^0 s


# ---------------------------------------------------------------------------------------------
# Fuzz: random and near-valid frames, bounded and seeded

FUZZ_SEED = 20261123
FUZZ_FRAMES = 50_000
OBJECTS = [(0x1000, 0), (0x1005, 0), (0x1006, 0), (0x1017, 0), (0x1400, 1), (0x1400, 2),
           (0x1600, 0), (0x1600, 1), (0x1800, 2), (0x1A00, 0), (0x1A00, 3), (0x2000, 0),
           (0x2001, 1), (0x2001, 4), (0x2003, 0), (0x2004, 0), (0x6007, 0), (0x6040, 0),
           (0x6041, 0), (0x6060, 0), (0x6065, 0), (0x6066, 0), (0x6076, 0), (0x607A, 0),
           (0x60B1, 0), (0x60C2, 1), (0x60C2, 2), (0x5000, 0), (0x6040, 3)]


def fuzz_frame(rng: random.Random) -> bytes:
    """A random request: garbage, a near-valid initiate, a segment, or a cut-off frame."""
    kind = rng.random()
    if kind < 0.25:  # garbage of any length
        return rng.randbytes(rng.randint(0, 8))
    index, subindex = rng.choice(OBJECTS)
    if kind < 0.65:  # an initiate request with any command flags and data
        command = rng.choice([0x20, 0x21, 0x22, 0x23, 0x27, 0x2B, 0x2F, 0x40, 0xA0, 0xC0, 0xC2])
        frame = struct.pack("<BHB", command | rng.randint(0, 3) << 2, index, subindex) + rng.randbytes(4)
    elif kind < 0.9:  # a segment, either direction, any toggle, any size field
        frame = bytes([rng.choice([0x00, 0x60]) | rng.randint(0, 0x1F)]) + rng.randbytes(7)
    else:  # a client abort
        frame = struct.pack("<BHBI", 0x80, index, subindex, rng.getrandbits(32))
    if rng.random() < 0.15:  # cut off
        frame = frame[:rng.randint(0, 7)]
    return frame


@pytest.mark.slow
def test_fuzz_the_sdo_server(sdo, table, caplog):
    """Random frames never raise, get one answer at most (never a general error, which would be a
    defect), never change the running table, and leave a server that answers a good read."""
    caplog.set_level(logging.ERROR, logger="hil_sim")
    blob = table.to_bytes()
    node = sdo.node
    node.sdo.download(0x2000, 0, blob)
    node.sdo[0x2001][1].raw = drv.CAM_COMMAND_ACTIVATE
    node.sdo[0x6060].raw = cia402.CYCLIC_SYNCHRONOUS_POSITION
    node.nmt.state = "OPERATIONAL"
    for controlword in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = controlword
    node.sdo[0x2004].raw = 1  # the drive runs the cam while the frames come
    assert sdo.drive.state == cia402.OPERATION_ENABLED
    sdo.drive.node.sdo.timeout_s = 0.005  # 5 cycles: stalled transfers time out in the fuzz too
    running = sdo.drive.active_table
    rng = random.Random(FUZZ_SEED)
    counts = {"frames": 0, "answered": 0, "aborts": 0, "syncs": 0}
    codes = set()
    start = time.perf_counter()
    for _ in range(FUZZ_FRAMES):
        frame = fuzz_frame(rng)
        answers = sdo.send(frame)
        counts["frames"] += 1
        assert len(answers) <= 1, (frame.hex(" "), answers)
        if answers:
            counts["answered"] += 1
            if answers[0][0] == 0x80:
                counts["aborts"] += 1
                code = struct.unpack_from("<I", answers[0], 4)[0]
                codes.add(code)
                assert code != 0x08000000, frame.hex(" ")  # a general error is a drive defect
        if rng.random() < 0.02:  # the control cycle runs between requests now and then
            answers = sdo.sync()
            counts["syncs"] += 1
            if answers:  # a stalled transfer timed out: one abort, nothing else
                assert abort_of(answers)[0] == drv.ABORT_TIMEOUT
                codes.add(drv.ABORT_TIMEOUT)
        assert sdo.drive.active_table is running
    elapsed = time.perf_counter() - start
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR], caplog.text
    # A client ends whatever transfer it left with an abort; the server then reads as new.
    assert sdo.send(b"\x80\x00\x00\x00\x00\x00\x04\x05") == []
    assert sdo.send(upload(0x1000)) == [b"\x43\x00\x10\x00\x92\x01\x02\x00"]
    assert sdo.node.sdo[0x1000].raw == 0x00020192
    assert sdo.node.sdo[0x2002].raw == table.crc32  # the running table never changed
    assert sdo.drive.active_table.to_bytes() == blob
    assert sdo.drive.state in cia402.STATUSWORD_OF_STATE
    # Every abort class of the server was reached (the fuzz is not stuck on one).
    assert {drv.ABORT_COMMAND_SPECIFIER, drv.ABORT_TOGGLE, drv.ABORT_TIMEOUT, 0x06020000,
            0x06090011, 0x06070012, 0x06070013, 0x06010002} <= codes, sorted(hex(c) for c in codes)
    print(f"fuzz: {counts} in {elapsed:.2f} s; abort codes {sorted(hex(c) for c in codes)}")


def test_a_mapping_entry_changed_in_use_must_still_fit_one_frame(sdo):
    # TPDO1 maps statusword (16), mode display (8) and position (32): 56 bits. Changing its mode
    # entry to a 32-bit object would make 72 bits, more than a CAN frame carries.
    entry = sdo.node.sdo[0x1A00][2]
    before = entry.raw
    with pytest.raises(canopen.SdoAbortedError) as error:
        entry.raw = 0x60640020
    assert error.value.code == drv.ABORT_PDO_LENGTH
    assert entry.raw == before
    sdo.node.sdo[0x1A00][2].raw = 0x60610008  # the same size: fine
