"""The virtual drive as a network node: `ecam drive --interface udp_multicast` in one process, an
unmodified canopen BaseNode402 master in another, inside a private network namespace with only
loopback, so no frame leaves the machine (tests/netns_master.py). The master connects with
`interface="ecam_udp"` and no frame filters, or with plain `udp_multicast` and the receive
filters the README gives for it; and the transport itself: why `ecam_udp` exists (plain
udp_multicast hands a sender its own frames) and that a datagram which is no frame does not
silence a node."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
SETUP = "ip link set lo up && ip route add 224.0.0.0/4 dev lo"


def _namespace_unavailable() -> str | None:
    for tool in ("unshare", "ip"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed (util-linux / iproute2)"
    probe = subprocess.run(["unshare", "-n", "sh", "-c", SETUP], capture_output=True, text=True)
    if probe.returncode != 0:
        return f"no private network namespace here: {probe.stderr.strip() or probe.returncode}"
    return None


def test_the_echo_free_bus_drops_only_its_own_frames_and_survives_a_stray_datagram():
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    code = """
import socket
import can
from hil_sim.udp_bus import DEFAULT_GROUP
a, b = can.Bus(interface="ecam_udp"), can.Bus(interface="ecam_udp")
plain = can.Bus(interface="udp_multicast", channel=DEFAULT_GROUP)
a.send(can.Message(arbitration_id=0x181, data=[1, 2], is_extended_id=False))
got_b, got_plain, echo = b.recv(2.0), plain.recv(2.0), a.recv(0.3)
plain.send(can.Message(arbitration_id=0x7, data=[3], is_extended_id=False))
got_a, plain_echo, _ = a.recv(2.0), plain.recv(2.0), b.recv(2.0)
print(got_b.arbitration_id, got_plain.arbitration_id, echo, got_a.arbitration_id,
      plain_echo.arbitration_id)
# A datagram on the group's port that is no python-can frame: plain udp_multicast raises from
# recv (a node that stops at the error goes deaf); ecam_udp drops it and hears the next frame.
stray = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
stray.sendto(b"\\xff not msgpack", (DEFAULT_GROUP, 43113))
try:
    plain.recv(2.0)
    print("plain: no error")
except can.CanOperationError:
    print("plain: CanOperationError")
a.send(can.Message(arbitration_id=0x182, data=[4], is_extended_id=False))
print(b.recv(2.0).arbitration_id, b.dropped)
for bus in (a, b, plain):
    bus.shutdown()
"""
    run = subprocess.run(["unshare", "-n", "sh", "-c", f'{SETUP} && exec "$0" -c "$1"', sys.executable, code],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    # b and plain hear a; a hears not itself but plain; plain hears itself (the echo ecam_udp drops)
    assert run.stdout.split("\n")[0].split() == ["385", "385", "None", "7", "7"]
    assert run.stdout.split("\n")[1] == "plain: CanOperationError"
    assert run.stdout.split("\n")[2].split() == ["386", "1"]  # b dropped the stray, heard a


STAGES = ("boot-up", "heartbeat", "sdo", "pdo configuration read", "mode CYCLIC SYNCHRONOUS POSITION",
          "state OPERATION ENABLED", "streamed 200 targets")
FAULT_STAGES = ("emcy 0x8611", "fault reset and re-enabled", "sync lost: emcy 0x8100")


@pytest.mark.slow
@pytest.mark.parametrize("interface", ["ecam_udp", "udp_multicast"])
def test_an_unmodified_canopen_master_in_another_process_runs_the_drive(interface):
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    run = subprocess.run(["unshare", "-n", "sh", "-c", f'{SETUP} && exec "$0" "$1" 3 "$2"', sys.executable,
                          str(HERE / "netns_master.py"), interface],
                         capture_output=True, text=True, timeout=120)
    steps = [line for line in run.stdout.splitlines() if line.startswith("step:")]
    assert run.returncode == 0 and run.stdout.strip().endswith("ok"), run.stdout + run.stderr
    stages = STAGES + (FAULT_STAGES if interface == "ecam_udp" else ()) + ("nmt STOPPED", "drive exit 0")
    for stage in stages:
        assert any(line.startswith(f"step: {stage}") for line in steps), (stage, steps)
