"""The drive against a hostile network peer, second round (issue 28, items 1, 7 and 11).

Frames that are no CAN frame (a float or NaN identifier, a DLC that does not match the data), an
NMT reset in the middle of an SDO download, a peer that forges the echo tag, a serving thread
that ends, a signal that lands while the main thread holds a lock, a large table verified while
SYNC, heartbeat and SDO go on. Lock-step tests run on python-can's in-process virtual bus; the
network tests run `udp_multicast` only inside a private network namespace with loopback alone
(tests/test_drive_network.py), so no datagram leaves the machine.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import struct
import subprocess
import sys
import threading

import can
import canopen
import pytest

import ecam
from ecam.errors import EcamError
from hil_sim.drive import cia402
from hil_sim.frames import frame_problem

from conftest import CAMS
from test_drive_network import SETUP, _namespace_unavailable
from test_drive_robustness import NODE, Session

#: Messages python-can builds without a check (as udp_multicast unpacks a peer's datagram):
#: each is no classic CAN frame. The issue's four identifiers first.
NOT_FRAMES = [
    dict(arbitration_id=2021.0, data=b"\x01"),
    dict(arbitration_id=1537.5, data=b"\x40\x00\x10\x00\x00\x00\x00\x00"),
    dict(arbitration_id=128.0, data=b""),
    dict(arbitration_id=math.nan, data=b"\x01\x03"),
    dict(arbitration_id=True, data=b""),
    dict(arbitration_id="0x80", data=b""),
    dict(arbitration_id=0x800, data=b""),
    dict(arbitration_id=-1, data=b""),
    dict(arbitration_id=0x601, data=b"\x40\x00\x10\x00", dlc=8),  # DLC 8, 4 bytes
    dict(arbitration_id=0x601, data=bytes(9)),  # 9 bytes: no classic frame
    dict(arbitration_id=0x080, data=b"", is_fd=True),
    dict(arbitration_id=0x080, data=b"", is_remote_frame=1),  # a flag that is no bool
]


@pytest.mark.parametrize("fields", NOT_FRAMES, ids=lambda f: repr(f["arbitration_id"])[:12])
def test_frame_problem_names_each_malformed_frame(fields):
    msg = can.Message(check=False, **{"is_extended_id": False, **fields})
    assert frame_problem(msg) is not None
    good = can.Message(arbitration_id=0x601, data=bytes(8), is_extended_id=False)
    assert frame_problem(good) is None


def test_frames_that_are_no_can_frames_are_dropped_and_counted(session, caplog):
    """Before, 128.0 reached canopen's network (a TypeError in its scanner) and the defect
    report raised again formatting the float with :03X: out of the runner, in a thread its end."""
    caplog.set_level(logging.ERROR, logger="hil_sim")
    session.boot()
    session.enable_csp()
    answered = len(session.frames)
    for fields in NOT_FRAMES:  # handed as received (the virtual bus would rebuild an FD frame)
        session.drive.runner.handle(can.Message(check=False, **{"is_extended_id": False, **fields}))
        session.master.settle()
    assert session.drive.runner.dropped == len(NOT_FRAMES)
    assert session.drive.defects == 0 and session.drive.cycles == 0
    assert len(session.frames) == answered  # nothing answered, no EMCY
    assert session.drive.state == cia402.OPERATION_ENABLED
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR], caplog.text
    assert session.node.sdo[0x1000].raw == 0x00020192  # and it serves on


def test_the_serving_thread_survives_a_float_identifier():
    """The drive in its own thread (as `ecam drive` runs it): a float identifier, then an SDO
    upload is answered. Before, the thread died and the upload timed out."""
    from hil_sim.bus import open_virtual_bus
    from hil_sim.drive import EDS_PATH, VirtualDrive

    channel = "test-hostile-thread"
    drive = VirtualDrive(channel=channel, node_id=NODE)
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    try:
        drive.start()
        node = network.add_node(canopen.RemoteNode(NODE, str(EDS_PATH)))
        node.sdo.RESPONSE_TIMEOUT = 10.0  # an answer comes at once or, before the fix, never
        for fields in NOT_FRAMES[:4]:
            network.bus.send(can.Message(check=False, is_extended_id=False, **fields))
        assert node.sdo[0x1000].raw == 0x00020192
        assert drive.runner.alive and drive.defects == 0
        assert drive.runner.dropped == 4
    finally:
        network.disconnect()
        drive.stop()


def test_the_drive_command_exits_non_zero_when_its_serving_thread_ends(monkeypatch):
    """A serving thread that ends (here: at once) leaves a process that answers nothing; the
    command notices and fails (exit 2), instead of running on deaf until SIGTERM and exiting 0."""
    from ecam.app.drive_command import drive_command
    from hil_sim.drive.runner import Runner

    monkeypatch.setattr(Runner, "_serve", lambda self: None)
    args = argparse.Namespace(interface="virtual", channel="test-hostile-deaf", node_id=NODE,
                              heartbeat_ms=None, scene=None)
    stop = threading.Event()
    outcome = []

    def run():
        try:
            outcome.append(drive_command(args, stop))
        except EcamError as exc:
            outcome.append(exc)

    thread = threading.Thread(target=run)
    thread.start()
    thread.join(30.0)  # a hang guard, not a timing assertion: the command returns at once
    stop.set()
    thread.join()
    assert isinstance(outcome[0], EcamError), outcome
    assert "serving thread" in str(outcome[0]) and "stopped" in str(outcome[0])


def test_the_signal_handler_takes_no_lock():
    """Python runs a signal handler in the main thread between two bytecodes, possibly inside
    ``Event.wait()`` with the event's lock held; a handler that called ``Event.set()`` then
    waited for that lock forever (a SIGTERM deadlock seen once). The handler runs here with such
    a lock held by this very thread, and must return."""
    from ecam.app import drive_command

    held = threading.Lock()
    signalled, restore = drive_command._stop_on_signals()
    try:
        handler = signal.getsignal(signal.SIGTERM)
        with held:  # as Event.wait() holds its condition's lock
            handler(signal.SIGTERM, None)
        assert signalled == [signal.SIGTERM]
        assert "lock" not in handler.__code__.co_names and "set" not in handler.__code__.co_names
    finally:
        restore()


# ---------------------------------------------------------------------------------------------
# Item 11: an NMT reset ends the SDO transfer in progress

def _segments(blob: bytes):
    """CiA 301 download segments of ``blob``: (command byte, 7 data bytes), toggling."""
    for k, start in enumerate(range(0, len(blob), 7)):
        chunk = blob[start:start + 7]
        last = start + 7 >= len(blob)
        command = ((k & 1) << 4) | ((7 - len(chunk)) << 1) | int(last)
        yield bytes([command]) + chunk.ljust(7, b"\0")


@pytest.mark.parametrize("reset", [0x81, 0x82], ids=["reset node", "reset communication"])
def test_an_nmt_reset_ends_an_sdo_download_in_progress(session, reset):
    """A table download, half sent; the master resets the node; the client sends the rest.
    Before, the rest was spliced onto the first half and the table went pending. Now the server
    starts afresh: the next segment is a request outside a transfer (abort 0x05040001) and no
    table is pending."""
    blob = ecam.compile_table(ecam.load_cam(CAMS / "combination_drrd.toml"), interp="cubic",
                              points=33, master_counts=36864, slave_counts_per_unit=100000).to_bytes()
    session.boot()
    session.send(0x600 + NODE, struct.pack("<BHBI", 0x21, 0x2000, 0, len(blob)))
    assert session.frames[-1][1][0] == 0x60
    segments = list(_segments(blob))
    half = len(segments) // 2
    for segment in segments[:half]:
        session.send(0x600 + NODE, segment)
    assert session.drive.node.sdo.transfer == "download"
    session.send(0x000, bytes([reset, NODE]))
    assert session.drive.node.sdo.transfer == "idle"
    session.send(0x600 + NODE, segments[half])
    can_id, data, _ = session.frames[-1]
    assert (can_id, data[0]) == (0x580 + NODE, 0x80)
    assert struct.unpack_from("<I", data, 4)[0] == 0x05040001
    for segment in segments[half + 1:]:
        session.send(0x600 + NODE, segment)
    assert session.drive.pending_table is None and session.drive.active_table is None


@pytest.fixture
def session():
    s = Session()
    yield s
    s.close()


# ---------------------------------------------------------------------------------------------
# Over UDP, in a private network namespace with loopback only

def _in_namespace(code: str, timeout: float = 90.0) -> subprocess.CompletedProcess:
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    return subprocess.run(["unshare", "-n", "sh", "-c", f'{SETUP} && exec "$0" -c "$1"', sys.executable, code],
                          capture_output=True, text=True, timeout=timeout)


def test_an_echo_cannot_be_forged_by_a_peer():
    """A peer that packs the receiving bus's own echo tag into its frame (the tag was in the
    datagram, where anyone can write it) is heard all the same: echoes are told by the socket
    they come from, and its own frame still never comes back to a bus."""
    run = _in_namespace("""
import can
from hil_sim.udp_bus import DEFAULT_GROUP
a = can.Bus(interface="ecam_udp")
peer = can.Bus(interface="udp_multicast", channel=DEFAULT_GROUP)
forged = getattr(a, "_tag", "ecam-udp:forged")
peer.send(can.Message(arbitration_id=0x181, data=[7], is_extended_id=False, channel=forged))
got = a.recv(2.0)
a.send(can.Message(arbitration_id=0x182, data=[8], is_extended_id=False))
echo = a.recv(0.3)
heard = peer.recv(2.0)
while heard is not None and heard.arbitration_id == 0x181:  # the peer's own echo first
    heard = peer.recv(2.0)
print(got and got.arbitration_id, echo, heard and heard.arbitration_id)
a.shutdown(); peer.shutdown()
""")
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["385", "None", "386"]


def test_one_datagram_with_a_float_identifier_does_not_silence_the_drive():
    """`ecam drive` over udp_multicast; a peer sends frames whose identifiers are 2021.0, 1537.5,
    128.0 and NaN (python-can packs them as they are); afterwards the drive still sends its
    heartbeat and answers an SDO upload, and SIGTERM stops it with exit 0. Before, the first of
    them ended the serving thread: no heartbeat, no SDO, and still exit 0."""
    run = _in_namespace("""
import signal, subprocess, sys, time
import can
from hil_sim.udp_bus import DEFAULT_GROUP
peer = can.Bus(interface="udp_multicast", channel=DEFAULT_GROUP)
drive = subprocess.Popen([sys.executable, "-m", "ecam.app", "drive", "--interface", "udp_multicast",
                          "--node-id", "3", "--heartbeat-ms", "50"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)

def wait_for(can_id, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        msg = peer.recv(0.1)
        if msg is not None and msg.arbitration_id == can_id:
            return msg
    return None

print("boot-up", wait_for(0x703, 20.0) is not None)
for can_id in (2021.0, 1537.5, 128.0, float("nan")):
    peer.send(can.Message(arbitration_id=can_id, data=[1], is_extended_id=False, check=False))
time.sleep(0.3)
print("heartbeat", wait_for(0x703, 5.0) is not None)
peer.send(can.Message(arbitration_id=0x603, data=[0x40, 0x00, 0x10, 0, 0, 0, 0, 0], is_extended_id=False))
answer = wait_for(0x583, 5.0)
print("sdo", answer is not None and bytes(answer.data[4:8]).hex())
drive.send_signal(signal.SIGTERM)
out, err = drive.communicate(timeout=20)
print("exit", drive.returncode)
print(out.strip().splitlines()[-2])
peer.shutdown()
""", timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split("\n")[:5] == ["boot-up True", "heartbeat True", "sdo 92010200", "exit 0",
                                          "dropped 4 received frames that were no CAN frames"], run.stdout + run.stderr


# ---------------------------------------------------------------------------------------------
# Item 7: a large table is verified off the real-time path

def _table(points: int, interp: str = "linear") -> ecam.CamTable:
    return ecam.compile_table(ecam.load_cam(CAMS / "combination_drrd.toml"), interp=interp, points=points,
                              master_counts=2**20, slave_counts_per_unit=100000)


def test_a_table_being_verified_stops_neither_sync_nor_sdo(session, monkeypatch):
    """The verification is held until the test releases it: meanwhile the download has been
    answered, SYNCs run cycles, the SDO server answers (0x2001:02 says VERIFYING) and an
    activation is refused (0x08000022); released, the table is pending and activates. Before,
    the verification ran inside the SDO handler, the drive's lock held, for seconds at the
    largest legal table."""
    from hil_sim.drive import cam_slot

    table = _table(2**12 + 1)
    release, threads = threading.Event(), []
    real_from_bytes = ecam.CamTable.from_bytes

    def held_from_bytes(data):
        threads.append(threading.current_thread())
        release.wait()
        return real_from_bytes(data)

    monkeypatch.setattr(cam_slot, "BACKGROUND_VERIFY_BYTES", 0)
    monkeypatch.setattr(cam_slot.CamTable, "from_bytes", held_from_bytes)
    session.boot()
    session.drive.cam.background = True  # as the drive serving an external master sets it
    session.enable_csp()
    sdo = session.node.sdo
    try:
        sdo.download(0x2000, 0, table.to_bytes())  # answered although the verification waits
        session.sync(5)
        assert session.drive.cycles == 5
        assert sdo[0x2001][2].raw & cam_slot.CAM_STATUS_VERIFYING
        with pytest.raises(canopen.SdoAbortedError) as error:
            sdo[0x2001][1].raw = 1
        assert error.value.code == 0x08000022
    finally:
        release.set()
        session.drive.cam.worker.join()
    assert threads and threads[0] is not threading.main_thread()
    status = sdo[0x2001][2].raw
    assert status & cam_slot.CAM_STATUS_PENDING and not status & cam_slot.CAM_STATUS_VERIFYING
    sdo[0x2001][1].raw = 1
    assert session.drive.active_table.crc32 == table.crc32


def test_a_bad_large_table_is_refused_by_the_worker_and_a_later_download_wins(session, monkeypatch):
    from hil_sim.drive import cam_slot

    monkeypatch.setattr(cam_slot, "BACKGROUND_VERIFY_BYTES", 0)
    session.boot()
    session.drive.cam.background = True
    sdo = session.node.sdo
    bad = bytearray(_table(2**10 + 1).to_bytes())
    bad[-1] ^= 0xFF  # the payload's CRC no longer matches
    sdo.download(0x2000, 0, bytes(bad))
    session.drive.cam.worker.join()
    assert sdo[0x2001][2].raw & cam_slot.CAM_STATUS_LAST_DOWNLOAD_REFUSED
    assert sdo[0x2001][3].raw == 0x08000020
    with pytest.raises(canopen.SdoAbortedError) as error:
        sdo[0x2001][1].raw = 1
    assert error.value.code == 0x08000022
    good = _table(2**10 + 1, "cubic")
    sdo.download(0x2000, 0, good.to_bytes())
    session.drive.cam.worker.join()
    sdo[0x2001][1].raw = 1
    assert session.drive.active_table.crc32 == good.crc32


@pytest.mark.parametrize("seed", range(3))
def test_large_legal_tables_are_verified_by_a_worker(session, seed):
    """Seeded: legal tables of 2^12+1 .. 2^16+1 points (up to 786 kB) downloaded to a drive that
    serves on its own thread: each is verified on a worker (never on the thread that handles the
    frames), is pending with its CRC, and activates; SYNC cycles run while it is verified."""
    import random

    from hil_sim.drive import cam_slot

    rng = random.Random(2026 + seed)
    table = _table(2 ** rng.randint(12, 16) + 1, rng.choice(["linear", "cubic", "quintic"]))
    blob = table.to_bytes()
    session.boot()
    session.drive.cam.background = True
    session.enable_csp()
    seen = []
    real = ecam.CamTable.from_bytes
    cam_slot_table = cam_slot.CamTable
    try:
        cam_slot.CamTable = type("Recording", (), {"from_bytes": staticmethod(
            lambda data: seen.append(threading.current_thread()) or real(data))})
        session.drive.cam.verify_download(blob)
        session.sync(3)
        if session.drive.cam.worker is not None:
            session.drive.cam.worker.join()
    finally:
        cam_slot.CamTable = cam_slot_table
    assert session.drive.cycles == 3
    if len(blob) > cam_slot.BACKGROUND_VERIFY_BYTES:
        assert seen and seen[0] is not threading.main_thread()
    assert session.drive.pending_table.crc32 == table.crc32
    session.node.sdo[0x2001][1].raw = 1
    assert session.drive.active_table.crc32 == table.crc32
