"""One bus for a whole machine (issue 22, item 2): TPDO transmission types and the CiA 301 SYNC
counter spread the drives' TPDOs over the SYNCs; the drive-side axes' master position goes once
per SYNC in one PDO every drive consumes; the bus sizing counts both.

The frame lengths are the rig's worst-case bit stuffing (hil_sim.bus.frame_bits = 47 + 8 n +
floor((34 + 8 n - 1) / 4)): SYNC 55 bits, with its counter byte 65; RPDO of 4 bytes (master
position) 95, 8 bytes (target and velocity offset) 135; TPDO1 7 bytes 125, TPDO2 6 bytes 115.
"""

from __future__ import annotations

import itertools
import sys
import tomllib
from pathlib import Path

import canopen
import numpy as np
import pytest
from canopen.sdo import SdoAbortedError

from ecam.errors import CamFileError, InputError
from hil_sim.bus import frame_bits, open_virtual_bus
from hil_sim.bus_sizing import size_bus
from hil_sim.drive import EDS_PATH, VirtualDrive
from hil_sim.machine import parse_machine
from hil_sim.rig import LockstepMaster
from hil_sim.rig.machine_run import run_machine
from hil_sim.sync_schedule import TpdoTiming

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_machine import machine_text  # noqa: E402 - the two-axis machine of tests/test_machine.py

NODE = 1
_channels = itertools.count()


def test_a_frame_reaches_every_other_node_once_with_its_content_and_not_its_sender():
    import can

    channel = f"bus-delivery-{next(_channels)}"
    sender, *nodes = [open_virtual_bus(channel) for _ in range(4)]
    try:
        frame = can.Message(arbitration_id=0x181, data=bytes(range(7)), is_extended_id=False,
                            timestamp=1.25)
        sender.send(frame)
        got = [node.recv(0) for node in nodes]
        assert [(m.arbitration_id, bytes(m.data), m.dlc, m.timestamp, m.is_rx) for m in got] == \
            [(0x181, bytes(range(7)), 7, 1.25, True)] * 3
        assert all(node.recv(0) is None for node in nodes)  # once each
        assert sender.recv(0) is None  # receive_own_messages is off
    finally:
        for bus in (sender, *nodes):
            bus.shutdown()


def test_the_frame_lengths_the_figures_below_use():
    assert [frame_bits(n) for n in (0, 1, 4, 6, 7, 8)] == [55, 65, 95, 115, 125, 135]


# ------------------------------------------------------------------ the drive (CiA 301 objects)

class Lockstep:
    """A drive and a canopen master in lock-step on an in-process virtual channel; records the
    SYNC number (1 = the first) of every TPDO1 (COB-ID 0x181) and every EMCY."""

    def __init__(self):
        channel = f"test-machine-bus-{next(_channels)}"
        self.drive = VirtualDrive(channel=channel, node_id=NODE)
        self.master = LockstepMaster(open_virtual_bus(channel), self.drive)
        self.node = self.master.add_node(canopen.RemoteNode(NODE, str(EDS_PATH)))
        self.syncs = 0
        self.tpdo1 = []
        self.emcy = []
        self.master.subscribe(0x180 + NODE, lambda *_: self.tpdo1.append(self.syncs))
        self.master.subscribe(0x80 + NODE, lambda cob, data, ts: self.emcy.append(
            int.from_bytes(data[:2], "little")))
        self.drive.boot()
        self.master.settle()

    def time_tpdo1(self, every: int, start: int) -> None:
        tpdo = self.node.tpdo
        tpdo.read()
        tpdo[1].trans_type = every
        tpdo[1].sync_start_value = start
        tpdo[1].save()

    def run(self, syncs: int, overflow: int = 0) -> None:
        self.node.nmt.state = "OPERATIONAL"
        self.master.settle()
        for _ in range(syncs):
            self.syncs += 1
            self.master.sync.transmit((self.syncs - 1) % overflow + 1 if overflow else None)

    def close(self):
        self.drive.close()
        self.master.bus.shutdown()


@pytest.fixture
def lockstep():
    rig = Lockstep()
    yield rig
    rig.close()


@pytest.mark.parametrize("every, start, overflow, expected", [
    (1, 0, 0, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]),
    (3, 0, 0, [3, 6, 9]),        # type n: every n-th SYNC, the first the n-th after OPERATIONAL
    (3, 2, 0, [3, 6, 9]),        # a start value without the counter is ignored (CiA 301)
    (3, 2, 4, [2, 5, 8]),        # the SYNC whose counter is 2 counts as the first
    (2, 4, 4, [4, 6, 8, 10]),
])
def test_tpdo_transmission_type_and_sync_start_value(lockstep, every, start, overflow, expected):
    if overflow:
        lockstep.node.sdo[0x1019].raw = overflow
    lockstep.time_tpdo1(every, start)
    lockstep.run(10, overflow)
    assert lockstep.tpdo1 == expected
    assert lockstep.drive.cycles == 10


def test_a_sync_of_the_wrong_length_is_no_sync_and_one_emcy(lockstep):
    """CiA 301 0x1019 = 0: the SYNC has no data; one with a counter byte is not taken (the drive
    does not run a period) and reported once with EMCY 0x8240 (unexpected SYNC data length);
    the other way round alike."""
    lockstep.run(2, overflow=3)  # counters 1, 2: the drive expects none
    assert lockstep.drive.cycles == 0 and lockstep.emcy == [0x8240]
    lockstep.run(1)
    assert lockstep.drive.cycles == 1
    lockstep.node.nmt.state = "PRE-OPERATIONAL"
    lockstep.node.sdo[0x1019].raw = 3
    lockstep.run(1)  # no counter now: not a SYNC either
    assert lockstep.drive.cycles == 1 and lockstep.emcy == [0x8240, 0x8240]


@pytest.mark.parametrize("index, subindex, value, code", [
    (0x1019, 0, 1, 0x06090030),      # reserved (CiA 301 7.5.2.22)
    (0x1019, 0, 241, 0x06090030),    # reserved
    (0x1800, 6, 241, 0x06090030),    # beyond 240 (CiA 301 7.5.2.37)
    (0x1800, 6, 2, 0x06090030),      # while TPDO1 is valid
])
def test_refused_sync_counter_and_start_values(lockstep, index, subindex, value, code):
    entry = lockstep.node.sdo[index]
    with pytest.raises(SdoAbortedError) as refused:
        (entry[subindex] if subindex else entry).raw = value
    assert refused.value.code == code


def test_the_sync_counter_is_fixed_while_the_sync_is_supervised(lockstep):
    """0x1019 may change only while the communication cycle period 0x1006 is 0 (abort
    0x08000022, as CANopenNode's OD_write_1019)."""
    lockstep.node.sdo[0x1006].raw = 1000
    with pytest.raises(SdoAbortedError) as refused:
        lockstep.node.sdo[0x1019].raw = 2
    assert refused.value.code == 0x08000022
    lockstep.node.sdo[0x1006].raw = 0
    lockstep.node.sdo[0x1019].raw = 240
    assert lockstep.node.sdo[0x1019].raw == 240


def test_the_schedule_arithmetic_matches_the_drive():
    """hil_sim.sync_schedule (the bus-free path's sampling) agrees with the parametrized drive
    runs above: cycle k runs on SYNC k + 1."""
    for every, start, overflow, syncs in ((3, 0, 0, [3, 6, 9]), (3, 2, 0, [3, 6, 9]),
                                          (3, 2, 4, [2, 5, 8]), (2, 4, 4, [4, 6, 8, 10])):
        mask = TpdoTiming(every, start, overflow).cycles(10)
        assert (np.flatnonzero(mask) + 1).tolist() == syncs


# ------------------------------------------------------------------------------- the sizing

def test_spreading_halves_the_peak_of_two_axes_on_every_second_sync():
    """Two controller-side axes, each an 8-byte RPDO on every SYNC and its two TPDOs (7 and 6
    bytes) on every second SYNC: unspread every TPDO comes on the same SYNC, 55 + 2 x (135 +
    125 + 115) = 805 bits; spread (SYNC counter, start values 1 and 2) one axis's TPDOs per
    SYNC: 65 + 2 x 135 + 240 = 575 bits; on average 55 + 270 + 240 = 565 (65 + ... = 575
    with the counter)."""
    axes = {"a": [8, (7, 2, 1), (6, 2, 1)], "b": [8, (7, 2, 0), (6, 2, 0)]}
    spread = size_bus(axes, 1_000_000, 0.001, 80.0, sync_counter=True)
    assert spread["bits_per_cycle"] == 575 and spread["unspread_bits_per_cycle"] == 805
    assert spread["spread"] and spread["fits"] and spread["mean_bits_per_cycle"] == 575
    same = size_bus({"a": [8, (7, 2, 0), (6, 2, 0)], "b": [8, (7, 2, 0), (6, 2, 0)]},
                    1_000_000, 0.001, 80.0)
    assert same["bits_per_cycle"] == same["unspread_bits_per_cycle"] == 805 and not same["fits"]
    assert same["mean_bits_per_cycle"] == 565


def test_more_axes_fit_when_spread():
    """Controller-side axes at 4 ms, 80 % of 1 Mbit/s (3200 bits). TPDOs on every SYNC: 375
    bits per axis, (3200 - 55) // 375 = 8 axes. TPDOs on every second SYNC, unspread: the same
    8 (they all land on one SYNC). Spread by the SYNC counter: the TPDOs alternate, each SYNC
    carries every RPDO (135) and half the TPDOs (240): n axes need 65 + 135 n + 240 ceil(n/2)
    <= 3200, n = 12 (3065; 13 need 3500)."""
    every = size_bus({"x": [8, 7, 6]}, 1_000_000, 0.004, 80.0)
    unspread = size_bus({"x": [8, (7, 2, 0), (6, 2, 0)]}, 1_000_000, 0.004, 80.0)
    spread = size_bus({"x": [8, (7, 2, 1), (6, 2, 1)]}, 1_000_000, 0.004, 80.0,
                      sync_counter=True)
    assert every["more_axes"]["x"] + 1 == 8 and unspread["more_axes"]["x"] + 1 == 8
    assert spread["more_axes"]["x"] + 1 == 12


def test_a_shared_frame_counts_once():
    """Two drive-side axes: per axis a 4-byte RPDO (95) and the TPDOs (240): 55 + 2 x 335 =
    725 bits; sharing the master position, 55 + 95 + 2 x 240 = 630, and a third drive-side
    axis adds only its TPDOs."""
    per_axis = size_bus({"a": [4, 7, 6], "b": [4, 7, 6]}, 1_000_000, 0.001, 80.0)
    shared = size_bus({"a": [7, 6], "b": [7, 6]}, 1_000_000, 0.001, 80.0, shared=[4])
    assert per_axis["bits_per_cycle"] == 725 and shared["bits_per_cycle"] == 630
    assert shared["shared_bits"] == 95
    assert per_axis["more_axes"]["a"] == 0  # 725 + 335 > 800
    assert shared["more_axes"]["a"] == 0  # 630 + 240 > 800
    wide = size_bus({"a": [7, 6], "b": [7, 6]}, 1_000_000, 0.002, 80.0, shared=[4])
    assert wide["more_axes"]["a"] == (1600 - 630) // 240


# ------------------------------------------------------------------------ machines on the rig

def _machine(axes, bus_lines="", drive_lines=(), bitrate=1_000_000, periods=0.1):
    text = machine_text(axes, bitrate=bitrate, periods=periods)
    text = text.replace(f"bitrate = {bitrate}\n", f"bitrate = {bitrate}\n{bus_lines}")
    for lines in drive_lines:  # one per axis, in order
        text = text.replace("following_error_window = 5000\n",
                            f"following_error_window = 5000 \n{lines}", 1)
    return parse_machine(tomllib.loads(text), source="m.toml")


CONTROLLER_PAIR = [dict(name="a", node=3, mode="controller", phase=0.0),
                   dict(name="b", node=5, mode="controller", phase=0.0)]


def test_spread_tpdos_fit_a_bus_where_unspread_ones_come_late():
    """At 750 kbit/s a 1 ms SYNC period has 750 bits. TPDOs on every second SYNC without the
    counter: 805 bits on every second SYNC, the higher COB-IDs late (b's set point); with the
    counter (overflow 2) and start values 1 and 2: 575 bits on every SYNC, nothing late, and
    every axis bit for bit as on the bus-free path (which samples the following error on the
    TPDOs' SYNCs alike). The busiest measured period is the sizing's."""
    types = ("tpdo_transmission_type = 2\n", "tpdo_transmission_type = 2\n")
    unspread = run_machine(_machine(CONTROLLER_PAIR, drive_lines=types, bitrate=750_000))
    bus = unspread.summary["bus"]
    assert bus["peak_bits"] == 805 and bus["late"]["b"]["late_set_points"] > 0
    assert bus["late"]["a"]["late_set_points"] == 0
    spread = _machine(CONTROLLER_PAIR, "sync_counter_overflow = 2\n",
                      [t + f"tpdo_sync_start = {s}\n" for t, s in zip(types, (1, 2))], 750_000)
    report, fast = run_machine(spread), run_machine(spread, path="fast")
    bus = report.summary["bus"]
    assert bus["peak_bits"] == bus["sizing"]["bits_per_cycle"] == 575
    assert bus["sizing"]["unspread_bits_per_cycle"] == 805 and bus["sizing"]["fits"]
    assert all(late["late_set_points"] == late["late_tpdos"] == 0 for late in bus["late"].values())
    assert report.passed, report.to_text()
    for a, b in zip(fast.axes, report.axes):
        for name in ("tracking_error", "following_error"):
            assert np.array_equal(a.series[name], b.series[name], equal_nan=True), name
        assert np.isnan(b.series["following_error"]).sum() == 50  # half the SYNCs
        assert b.summary["bus"]["missing_status_samples"] == 0
    assert "with the TPDOs spread by the SYNC counter, 805 bits" in report.to_text()


DRIVE_PAIR = [dict(name="a", node=3, mode="drive", phase=0.0),
              dict(name="b", node=5, mode="drive", phase=0.0)]


def test_one_shared_master_position_pdo_gives_the_same_axes():
    """Two drive-side axes at the same phase: one master position PDO (on the first axis's
    RPDO3 COB-ID, 0x403) that both drives consume instead of one each: every series and check
    of every axis the same, bit for bit, one 95-bit frame less per SYNC period."""
    per_axis = run_machine(_machine(DRIVE_PAIR))
    shared = run_machine(_machine(DRIVE_PAIR, 'master_position_pdo = "shared"\n'))
    for a, b in zip(per_axis.axes, shared.axes):
        for name in a.series:
            assert np.array_equal(a.series[name], b.series[name], equal_nan=True), name
        assert ([c.to_dict() for c in a.checks if c.name != "bus_load"]
                == [c.to_dict() for c in b.checks if c.name != "bus_load"])
    before, after = per_axis.summary["bus"], shared.summary["bus"]
    assert before["peak_bits"] - after["peak_bits"] == 95
    assert before["frames"] - after["frames"] == before["cycles"]
    assert before["sizing"]["bits_per_cycle"] == 725 and after["sizing"]["bits_per_cycle"] == 630
    assert after["sizing"]["axis_bits"] == {"a": 240, "b": 240}
    assert "the master position goes once for every drive-side axis" in shared.to_text()


def test_a_shared_master_position_needs_the_same_position():
    machine = _machine([DRIVE_PAIR[0], dict(DRIVE_PAIR[1], phase=90.0)],
                       'master_position_pdo = "shared"\n')
    with pytest.raises(InputError, match="bus.master_position_pdo: 'shared' should carry one "
                                         "master position .* phase 90 against 0"):
        run_machine(machine)


@pytest.mark.parametrize("bus, drive, message", [
    ("", "tpdo_sync_start = 1\n", "drive.tpdo_sync_start: 1 should be 0 without a SYNC counter"),
    ("sync_counter_overflow = 2\n", "tpdo_sync_start = 3\n",
     "drive.tpdo_sync_start: 3 should be <= bus.sync_counter_overflow (2)"),
    ("sync_counter_overflow = 1\n", "", "bus.sync_counter_overflow: 1 should be 0"),
    ("", "tpdo_transmission_type = 241\n", "drive.tpdo_transmission_type: 241"),
])
def test_bad_timing_fields_name_the_field(bus, drive, message):
    with pytest.raises(CamFileError) as raised:
        _machine(CONTROLLER_PAIR, bus, [drive])
    assert message in str(raised.value) and "\n" not in str(raised.value)


# ---------------------------------------------------------------- `ecam drive` for several nodes

def test_ecam_drive_checks_every_node_id_before_opening_the_bus(capsys):
    """1.2.3.4 is no multicast group: had the bus been opened first, that would be the error."""
    from ecam.app import cli
    for ids, message in (("5,5", "node_id: 5 should be distinct"),
                         ("5,128", "node_id: 128 should be an integer in 1..127")):
        status = cli.main(["drive", "--interface", "udp_multicast", "--channel", "1.2.3.4",
                           "--node-id", ids])
        err = capsys.readouterr().err
        assert status == 2 and err.count("\n") == 1 and message in err, err


def test_ecam_drive_serves_one_drive_per_node_in_one_process():
    """`--node-id 5 --node 6` (repeated, or 5,6): two drives on one in-process channel, each
    with its own boot-up, SDO server and node id; a canopen master in this process reads both."""
    import threading

    from ecam.app.cli import build_parser
    from ecam.app.drive_command import drive_command

    channel = f"test-machine-bus-drive-{next(_channels)}"
    args = build_parser().parse_args(["drive", "--interface", "virtual", "--channel", channel,
                                      "--node-id", "5", "--node", "6"])
    assert args.node_id == [[5], [6]]
    network = canopen.Network()
    network.NOTIFIER_CYCLE = 0.05
    network.connect(interface="virtual", channel=channel, receive_own_messages=False)
    booted = {n: threading.Event() for n in (5, 6)}
    nodes = {}
    for n, ready in booted.items():
        nodes[n] = network.add_node(canopen.RemoteNode(n, str(EDS_PATH)))
        nodes[n].sdo.RESPONSE_TIMEOUT = 2.0
        nodes[n].nmt.add_heartbeat_callback(lambda state, ready=ready: ready.set()
                                            if state == 0 else None)
    stop, result = threading.Event(), []
    worker = threading.Thread(target=lambda: result.append(drive_command(args, stop)))
    worker.start()
    try:
        assert all(ready.wait(5.0) for ready in booted.values()), "no boot-up from both"
        for n, node in nodes.items():
            assert node.sdo[0x1000].raw == 0x00020192
            node.sdo[0x1017].raw = 100 * n  # each its own object dictionary
        assert [nodes[n].sdo[0x1017].raw for n in (5, 6)] == [500, 600]
    finally:
        stop.set()
        worker.join(10.0)
        network.disconnect()
    assert result == [0]


def _namespace_unavailable() -> str | None:
    import shutil
    import subprocess
    for tool in ("unshare", "ip"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed (util-linux / iproute2)"
    probe = subprocess.run(["unshare", "-n", "sh", "-c", NETNS_SETUP], capture_output=True,
                           text=True)
    if probe.returncode != 0:
        return f"no private network namespace here: {probe.stderr.strip() or probe.returncode}"
    return None


NETNS_SETUP = "ip link set lo up && ip route add 224.0.0.0/4 dev lo"


@pytest.mark.slow
def test_one_canopen_master_in_another_process_runs_two_nodes_of_one_drive_process():
    """canopen's BaseNode402 for nodes 5 and 6 in one process, `ecam drive --interface
    udp_multicast --node-id 5,6` in another, inside a private network namespace with loopback
    only (tests/netns_machine_master.py): both boot, both are configured by SDO, enabled in
    CSP and follow their own ramps, the drive process stops on SIGTERM with exit 0."""
    import subprocess
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    script = Path(__file__).resolve().parent / "netns_machine_master.py"
    run = subprocess.run(["unshare", "-n", "sh", "-c", f'{NETNS_SETUP} && exec "$0" "$1" 5 6',
                          sys.executable, str(script)], capture_output=True, text=True,
                         timeout=120)
    steps = [line for line in run.stdout.splitlines() if line.startswith("step:")]
    assert run.returncode == 0 and run.stdout.strip().endswith("ok"), run.stdout + run.stderr
    for stage in ("boot-up of nodes 5, 6", "node 5 streamed", "node 6 streamed",
                  "both drives followed", "drive exit 0: virtual drives stopped"):
        assert any(line.startswith(f"step: {stage}") for line in steps), (stage, steps)
