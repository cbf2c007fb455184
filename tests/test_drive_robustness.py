"""The virtual drive against hostile and unusual frames on its process-data and network-management
services (issue 14; issue 13, item 1): echoes of its own frames, frames a CANopen node does not
take, a bounded seeded fuzz of RPDO, SYNC and NMT frames (the SDO server has its own fuzz in
tests/test_drive_sdo.py), and an exception escaping a handler.

Everything runs in lock-step on python-can's in-process virtual bus: no threads, simulated time,
exact frames.
"""

from __future__ import annotations

import itertools
import logging
import math
import random
import struct

import can
import canopen
import pytest

import ecam
from hil_sim.bus import LockstepVirtualBus, open_virtual_bus
from hil_sim.drive import EDS_PATH, VirtualDrive, cia402
from hil_sim.drive.objects import saturate_int32
from hil_sim.rig import LockstepMaster

from conftest import CAMS

NODE = 1
_channels = itertools.count()
#: Every COB-ID the drive sends on (EMCY, TPDO1..4, SDO response, heartbeat).
DRIVE_SENDS = [0x80 + NODE, 0x180 + NODE, 0x280 + NODE, 0x380 + NODE, 0x480 + NODE, 0x580 + NODE,
               0x700 + NODE]


class Session:
    """A drive and a lock-step master that logs every frame the drive sends."""

    def __init__(self, echo: bool = False):
        channel = f"test-drive-robust-{next(_channels)}"
        # An echoing transport hands the drive every frame it sends (as udp_multicast does).
        bus = LockstepVirtualBus(channel=channel, receive_own_messages=echo, preserve_timestamps=True)
        self.drive = VirtualDrive(bus=bus, node_id=NODE)
        self.drive_bus = bus
        self.master = LockstepMaster(open_virtual_bus(channel), self.drive)
        self.node = self.master.add_node(canopen.RemoteNode(NODE, str(EDS_PATH)))
        self.node.sdo.RESPONSE_TIMEOUT = 0.01  # lock-step: an answer is there at once or never
        self.frames: list[tuple[int, bytes, float]] = []
        for can_id in DRIVE_SENDS:
            self.master.subscribe(can_id, self._log)
        self.handled = 0  # frames the drive took off its bus
        process = self.drive.process

        def counted() -> int:  # the lock-step master calls it too
            count = process()
            self.handled += count
            return count

        self.drive.process = counted

    def _log(self, can_id, data, timestamp):
        self.frames.append((can_id, bytes(data), timestamp))

    def process(self) -> None:
        self.drive.process()

    def send(self, can_id: int, data: bytes, **flags) -> None:
        self.master.bus.send(can.Message(arbitration_id=can_id, data=data, timestamp=self.drive.time_s,
                                         check=False, **{"is_extended_id": False, **flags}))
        self.process()
        self.master.settle()

    def sync(self, count: int = 1) -> None:
        for _ in range(count):
            self.master.sync.transmit()
            self.process()

    def boot(self) -> None:
        self.drive.boot()
        self.process()
        self.master.settle()

    def enable_csp(self) -> None:
        sdo = self.node.sdo
        sdo[0x6060].raw = cia402.CYCLIC_SYNCHRONOUS_POSITION
        self.node.nmt.state = "OPERATIONAL"
        for controlword in (0x06, 0x07, 0x0F):
            sdo[0x6040].raw = controlword
        self.process()

    def close(self) -> None:
        self.drive.close()
        self.drive_bus.shutdown()
        self.master.bus.shutdown()


@pytest.fixture
def session():
    s = Session()
    yield s
    s.close()


# ---------------------------------------------------------------------------------------------
# Echoes: a transport that hands a sender its own frames back (udp_multicast does)

def _script(s: Session) -> None:
    """Boot, configure by SDO, enable CSP, stream, fault on a following error, reset, re-enable,
    stop by NMT: every service the drive has, as a master drives it."""
    s.boot()
    sdo = s.node.sdo
    sdo[0x1017].raw = 5  # heartbeat every 5 ms: heartbeats in the stream too
    sdo[0x6065].raw = 5000  # following error window [counts]
    s.enable_csp()
    start = sdo[0x6064].raw
    for k in range(1, 101):
        s.send(0x301, struct.pack("<ii", start + 40 * k, 40_000))  # RPDO2: target, velocity offset
        s.sync()
    s.send(0x301, struct.pack("<ii", start + 10**7, 0))  # far beyond the window: EMCY 0x8611
    s.sync(3)
    assert s.drive.state == cia402.FAULT
    s.send(0x201, struct.pack("<Hb", 0x80, 8))  # RPDO1: fault reset
    s.send(0x201, struct.pack("<Hb", 0x06, 8))
    s.send(0x201, struct.pack("<Hb", 0x0F, 8))
    s.sync()
    position = sdo[0x6064].raw
    for k in range(1, 51):
        s.send(0x301, struct.pack("<ii", position + 40 * k, 40_000))
        s.sync()
    s.node.nmt.state = "STOPPED"
    s.sync(10)


def test_the_drive_ignores_the_echoes_of_its_own_frames():
    plain, echoed = Session(echo=False), Session(echo=True)
    try:
        _script(plain)
        _script(echoed)
        # The drive on the echoing bus took its own frames back...
        assert echoed.handled > plain.handled + len(plain.frames) // 2
        # ...and answered exactly as without them: the same frames, bytes and times.
        assert echoed.frames == plain.frames
        assert (echoed.drive.state, echoed.drive.nmt_state) == (plain.drive.state, plain.drive.nmt_state)
        assert echoed.drive.axis.position_counts == plain.drive.axis.position_counts
        emcy = [struct.unpack_from("<H", data)[0] for cid, data, _ in plain.frames if cid == 0x81]
        assert emcy == [0x8611, 0x0000]  # the fault, then its reset
        assert plain.drive.nmt_state == cia402.STOPPED
        assert echoed.drive.defects == plain.drive.defects == 0
    finally:
        plain.close()
        echoed.close()


# ---------------------------------------------------------------------------------------------
# Frames a CANopen node does not take

def test_extended_remote_and_error_frames_are_ignored(session):
    session.boot()
    session.enable_csp()
    answered = len(session.frames)
    request = struct.pack("<BHB4x", 0x40, 0x1000, 0)
    session.send(0x601, request, is_extended_id=True)  # 29-bit 0x00000601 is not the SDO COB-ID
    session.send(0x000, bytes([0x02, NODE]), is_extended_id=True)  # nor is this an NMT stop
    session.send(0x201, struct.pack("<Hb", 0x00, 8), is_remote_frame=True)  # an RTR is no RPDO
    session.send(0x080, b"", is_error_frame=True)  # nor an error frame a SYNC
    assert len(session.frames) == answered
    assert session.drive.state == cia402.OPERATION_ENABLED
    assert session.drive.nmt_state == cia402.OPERATIONAL
    assert session.drive.cycles == 0
    session.send(0x601, request)  # the same request on the 11-bit COB-ID is answered
    assert session.frames[-1][:2] == (0x581, b"\x43\x00\x10\x00\x92\x01\x02\x00")


# ---------------------------------------------------------------------------------------------
# An exception that escapes a handler: logged, a fault with EMCY 0x6100, and the drive goes on

def test_an_exception_escaping_a_handler_is_logged_and_faults_the_drive(session, caplog):
    session.boot()
    session.enable_csp()

    def defect(can_id, data, timestamp):
        raise RuntimeError("a defect")

    session.drive.network.subscribe(0x123, defect)
    with caplog.at_level(logging.ERROR, logger="hil_sim"):
        session.send(0x123, b"\x01")
    assert "drive defect while handling frame 0x123 01" in caplog.text
    assert "RuntimeError: a defect" in caplog.text
    assert session.drive.defects == 1
    session.sync()
    assert session.drive.state == cia402.FAULT
    assert session.node.sdo[0x603F].raw == 0x6100  # CiA 301: internal software
    emcy = [data for cid, data, _ in session.frames if cid == 0x81]
    assert struct.unpack_from("<HB", emcy[-1]) == (0x6100, 0x01)
    assert session.node.sdo[0x1000].raw == 0x00020192  # the drive serves on


# ---------------------------------------------------------------------------------------------
# Issue 14, items 12 and 1, as reproduced: one master jump, one hostile blob

def _drive_side_cam(s: Session) -> bytes:
    """A booted drive running the combination cam drive-side, its master position at 26 624
    counts (the rise's steepest slope), following-error monitoring off."""
    table = ecam.compile_table(ecam.load_cam(CAMS / "combination_drrd.toml"), interp="cubic",
                               points=289, master_counts=36864, slave_counts_per_unit=100000)
    blob = table.to_bytes()
    s.boot()
    sdo = s.node.sdo
    sdo.download(0x2000, 0, blob)
    sdo[0x2001][1].raw = 1  # activate
    sdo[0x6065].raw = 0xFFFFFFFF  # no following-error fault: the cam runs through the jump
    s.enable_csp()
    sdo[0x2004].raw = 1  # drive-side cam
    for master in (26544, 26584, 26624):  # RPDO3 maps the master position 0x2003
        s.send(0x401, struct.pack("<i", master))
        s.sync()
    return blob


def test_a_master_jump_of_2_to_the_30_saturates_the_velocity_offset(session, caplog):
    """A master that jumps by about 2^30 counts in one 1 ms cycle at the rise's steepest slope
    (-24 slave counts per master count) asks for a velocity offset of about -2.6e13 counts/s.
    0x60B1 is INTEGER32 (CiA 402): it saturates at -2^31 as a drive's does, uploads, and an NMT
    reset-communication (which re-encodes every object) goes through; before, 0x60B1 held
    -2.6e13, its upload aborted and the reset raised ValueError out of the drive."""
    caplog.set_level(logging.ERROR, logger="hil_sim")
    _drive_side_cam(session)
    sdo = session.node.sdo
    steady = sdo[0x60B1].raw
    assert -10**6 < steady < -9 * 10**5  # 40 counts/ms on a slope of about -24: about -9.6e5
    jump = 2**30 - 4096  # a whole number of periods (36 864 = 9 x 2^12) short of 2^30: same slope
    session.send(0x401, struct.pack("<i", 26624 + jump))
    session.sync()
    assert session.drive.values[(0x60B1, 0)] == -(2**31)
    assert sdo[0x60B1].raw == -(2**31)  # uploads (an abort would raise)
    assert session.drive.state == cia402.OPERATION_ENABLED
    session.node.nmt.send_command(0x82)  # reset communication
    session.process()
    session.master.settle()
    assert session.drive.nmt_state == cia402.PRE_OPERATIONAL
    assert session.drive.defects == 0
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR], caplog.text


def test_the_issue_14_preshift_blob_is_refused_by_the_drive(session):
    """combination_drrd.bin with slope_preshift (byte 15) = 16 + F + W = 64 and its header CRC
    recomputed: downloaded to a drive running a table, it is refused (0x08000020, cannot be
    stored), cannot be activated (0x08000022) and the running table runs on. Before, the Python
    loader accepted it and the drive activated it."""
    import zlib
    from pathlib import Path

    running_blob = _drive_side_cam(session)
    running = session.drive.active_table
    blob = bytearray((Path(__file__).resolve().parents[1] / "firmware_tables" / "tables"
                      / "combination_drrd.bin").read_bytes())
    assert 16 + blob[11] + blob[12] == 64
    blob[15] = 64
    struct.pack_into("<I", blob, 60, zlib.crc32(bytes(blob[:60])))
    sdo = session.node.sdo
    with pytest.raises(canopen.SdoAbortedError) as error:
        sdo.download(0x2000, 0, bytes(blob))
    assert error.value.code == 0x08000020
    with pytest.raises(canopen.SdoAbortedError) as error:
        sdo[0x2001][1].raw = 1
    assert error.value.code == 0x08000022
    assert session.drive.active_table is running
    assert session.drive.active_table.to_bytes() == running_blob
    session.send(0x401, struct.pack("<i", 26664))
    session.sync()
    assert session.drive.state == cia402.OPERATION_ENABLED


# ---------------------------------------------------------------------------------------------
# Fuzz: RPDO, SYNC and NMT frames, bounded and seeded

FUZZ_SEED = 20261124
FUZZ_EPISODES = 100
FRAMES_PER_EPISODE = 100
#: Mappings the fuzz puts into RPDO1 now and then (by SDO, as a master reconfigures): every
#: writable mappable object of the drive, in different orders and sizes.
RPDO_MAPPINGS = [
    [0x60400010, 0x60600008],  # controlword, mode
    [0x607A0020, 0x60B10020],  # target, velocity offset
    [0x20030020, 0x60400010],  # master position (drive-side cam), controlword
    [0x60600008, 0x607A0020, 0x60400010],
    [0x60B10020],
]
#: Live objects whose values come from arithmetic (the cam, the axis): each must still fit its
#: data type (a 0x60B1 that left INTEGER32 made its upload abort and the next reset raise, issue 14).
COMPUTED_OBJECTS = [0x6041, 0x6061, 0x6064, 0x606C, 0x6077, 0x607A, 0x60B1, 0x60F4, 0x603F, 0x1001]
#: Statusword bits 0..6 name the CiA 402 state (cia402.STATUSWORD_OF_STATE); the drive may add these.
STATE_BITS = 0x007F
EXTRA_BITS = cia402.SW_REMOTE | cia402.SW_FOLLOWING_COMMAND | cia402.SW_FOLLOWING_ERROR
#: INTEGER32 values at and near the edges, and jumps a master may make in one cycle.
EDGES = [0, 1, -1, 2**31 - 1, -2**31, 2**30, -2**30, 2**31 - 40, -2**31 + 40]


def _remap(s: Session, rng: random.Random) -> None:
    sdo = s.node.sdo
    entries = rng.choice(RPDO_MAPPINGS)
    sdo[0x1600][0].raw = 0
    for sub, entry in enumerate(entries, start=1):
        sdo[0x1600][sub].raw = entry
    sdo[0x1600][0].raw = len(entries)
    sdo[0x1400][2].raw = rng.choice([0x01, 0x05, 0xFF])  # synchronous, every 5th SYNC, event


def _int32(rng: random.Random, near: int) -> int:
    """An INTEGER32 at an edge, a jump from ``near``, or a small step from it."""
    kind = rng.random()
    value = rng.choice(EDGES) if kind < 0.3 else near + rng.choice([2**30, -2**30, 10**6]) \
        if kind < 0.5 else near + rng.randint(-500, 500)
    return (value + 2**31) % 2**32 - 2**31


def _setpoint_frame(rng: random.Random, s: Session) -> tuple[int, bytes]:
    position = s.drive.values[(0x6064, 0)]
    if rng.random() < 0.5:  # RPDO2: target position, velocity offset
        return 0x301, struct.pack("<ii", _int32(rng, position), rng.choice(EDGES + [0, 40_000]))
    s.master_position = _int32(rng, s.master_position)  # RPDO3: the cam's master position
    return 0x401, struct.pack("<i", s.master_position)


def _garbage_frame(rng: random.Random) -> tuple[int, bytes]:
    can_id = rng.choice([0x000, 0x080, 0x201, 0x301, 0x401, 0x501])
    return can_id, rng.randbytes(rng.randint(0, 8))


def _control_frame(rng: random.Random) -> tuple[int, bytes]:
    controlword = rng.choice([0x00, 0x02, 0x06, 0x07, 0x0F, 0x0B, 0x80, 0x8F, 0x1F, rng.getrandbits(16)])
    return 0x201, struct.pack("<Hb", controlword, rng.choice([8, 8, 8, 0, -1, 127, 1]))


def _malformed_frame(rng: random.Random) -> can.Message:
    """A message no CAN controller delivers but a udp_multicast peer can pack: an identifier that
    is a float, NaN, a bool, a string or out of range, or a DLC that is not the data's length."""
    can_id = rng.choice([0x000, 0x080, 0x201, 0x301, 0x401, 0x601])
    data = rng.randbytes(rng.randint(0, 8))
    kind = rng.randrange(4)
    if kind == 0:
        can_id = rng.choice([float(can_id), can_id + 0.5, math.nan, math.inf, True, str(can_id)])
    elif kind == 1:
        can_id = rng.choice([0x800, -1, 2**31, 0x1FFFFFFF])
    elif kind == 2:
        return can.Message(arbitration_id=can_id, data=data, dlc=(len(data) + rng.randint(1, 7)) % 16,
                           is_extended_id=False, check=False)
    else:
        data = rng.randbytes(rng.randint(9, 64))
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=False, check=False)


def _nmt_frame(rng: random.Random) -> tuple[int, bytes]:
    command = rng.choice([0x01] * 4 + [0x02, 0x80, 0x81, 0x82, rng.randint(0, 255)])
    target = rng.choice([0, NODE, NODE + 1, rng.randint(0, 255)])
    return 0x000, bytes([command, target, *rng.randbytes(rng.randint(0, 6))])[:rng.randint(0, 8)]


def _restore(s: Session, blob: bytes, rng: random.Random) -> None:
    """What a master does to get the drive running again: start, reset a fault, reload the cam
    after a reset of the application, enable CSP, choose the cam mode."""
    s.node.nmt.state = "OPERATIONAL"
    s.process()
    sdo = s.node.sdo
    if s.drive.state in (cia402.FAULT, cia402.FAULT_REACTION_ACTIVE):
        s.sync()
        sdo[0x6040].raw = 0x00
        sdo[0x6040].raw = 0x80
    if s.drive.active_table is None:
        sdo.download(0x2000, 0, blob)
        sdo[0x2001][1].raw = 1
    # Following-error monitoring on or off (0xFFFFFFFF): off, the axis chases any target with
    # its torque limit, and the cam runs through jumps of its master.
    sdo[0x6065].raw = rng.choice([100_000, 0xFFFFFFFF])
    s.enable_csp()
    s.master_position = rng.randint(-2**31, 2**31 - 1)
    s.send(0x401, struct.pack("<i", s.master_position))
    s.sync()
    sdo[0x2004].raw = rng.randint(0, 1)
    if rng.random() < 0.2:
        _remap(s, rng)


def test_fuzz_rpdo_sync_and_nmt_frames(session, caplog):
    """Episodes of random RPDO, SYNC and NMT frames, each begun the way a master brings a drive
    back (start, fault reset, cam reloaded, CSP enabled, cam mode on or off, RPDO1 remapped now
    and then): set points at the edges of INTEGER32 and jumps of 2^30 counts (controller-side
    and drive-side cam), random controlwords and modes, NMT commands, garbage of any length.
    Nothing escapes a handler (no defect logged), every computed value keeps its data type,
    every statusword names a CiA 402 state, and afterwards a master runs the drive as new."""
    caplog.set_level(logging.ERROR, logger="hil_sim")
    blob = ecam.compile_table(ecam.load_cam(CAMS / "combination_drrd.toml"), interp="cubic",
                              points=33, master_counts=36864, slave_counts_per_unit=100000).to_bytes()
    session.boot()
    sdo = session.node.sdo
    values = session.drive.values
    computed = [((index, 0), session.drive.objects.find((index, 0))) for index in COMPUTED_OBJECTS]
    episodes = {"setpoints": lambda rng: _setpoint_frame(rng, session),
                "control": _control_frame, "nmt": _nmt_frame, "garbage": _garbage_frame}
    rng = random.Random(FUZZ_SEED)
    # Frames that are no CAN frame (issue 28) come between the others from a random stream of
    # their own, so the episodes above run as they did: each is dropped and counted, nothing else.
    malformed = random.Random(FUZZ_SEED + 28)
    sent_malformed = 0
    counts = dict.fromkeys(["frames", "syncs", "fault cycles", "cam cycles", "csp cycles"], 0)
    for _ in range(FUZZ_EPISODES):
        _restore(session, blob, rng)
        kind = rng.choice(list(episodes))
        counts[kind] = counts.get(kind, 0) + 1
        make = episodes[kind]
        for _ in range(FRAMES_PER_EPISODE):
            can_id, data = make(rng) if rng.random() < 0.7 else (0x080, b"")
            session.send(can_id, data)
            counts["frames"] += 1
            if malformed.random() < 0.05:
                session.drive.runner.handle(_malformed_frame(malformed))
                sent_malformed += 1
            if can_id == 0x080:
                counts["syncs"] += 1
                state = session.drive.state
                counts["fault cycles"] += state == cia402.FAULT
                if state == cia402.OPERATION_ENABLED:
                    counts["csp cycles"] += 1
                    counts["cam cycles"] += session.drive.cam.drives_the_target
            assert session.drive.state in cia402.STATUSWORD_OF_STATE
            for key, obj in computed:  # each value still packs into its data type
                obj.encode_raw(values[key])
        if session.drive.nmt_state != cia402.STOPPED:
            for index in COMPUTED_OBJECTS:
                sdo[index].raw  # each still uploads (an abort raises)
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR], caplog.text
    assert session.drive.defects == 0
    assert session.drive.runner.dropped == sent_malformed > 100
    # Every TPDO1 the drive sent has a statusword naming a state, and the fuzz reached them all.
    states = {word: name for name, word in cia402.STATUSWORD_OF_STATE.items()}
    seen = set()
    for can_id, data, _ in session.frames:
        if can_id == 0x181:
            statusword, _mode, _position = struct.unpack("<Hbi", data)
            assert statusword & ~(STATE_BITS | EXTRA_BITS) == 0, hex(statusword)
            seen.add(states[statusword & STATE_BITS])
    assert {cia402.OPERATION_ENABLED, cia402.FAULT, cia402.SWITCH_ON_DISABLED,
            cia402.QUICK_STOP_ACTIVE} <= seen, seen
    assert counts["cam cycles"] > 300 and counts["csp cycles"] > 1000 and counts["fault cycles"] > 100, counts
    # Afterwards a master resets the node and runs it as new.
    session.node.nmt.state = "RESET"
    session.process()
    session.master.settle()
    assert session.drive.nmt_state == cia402.PRE_OPERATIONAL
    session.enable_csp()
    assert session.drive.state == cia402.OPERATION_ENABLED
    start = sdo[0x6064].raw
    session.send(0x301, struct.pack("<ii", start + 100, 0))
    session.sync(50)
    assert abs(sdo[0x6064].raw - (start + 100)) <= 2
    print(f"fuzz: {counts}, TPDO1 states {sorted(seen)}")
