"""The virtual drive as a network node: `ecam drive --interface udp_multicast` in one process, an
unmodified canopen BaseNode402 master (no frame filters) in another, inside a private network
namespace with only loopback, so no frame leaves the machine (tests/netns_master.py)."""

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


def test_the_echo_free_bus_drops_only_its_own_frames():
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    code = """
import can
from hil_sim.udp_bus import DEFAULT_GROUP
a, b = can.Bus(interface="ecam_udp"), can.Bus(interface="ecam_udp")
plain = can.Bus(interface="udp_multicast", channel=DEFAULT_GROUP)
a.send(can.Message(arbitration_id=0x181, data=[1, 2], is_extended_id=False))
got_b, got_plain, echo = b.recv(2.0), plain.recv(2.0), a.recv(0.3)
plain.send(can.Message(arbitration_id=0x7, data=[3], is_extended_id=False))
got_a = a.recv(2.0)
print(got_b.arbitration_id, got_plain.arbitration_id, echo, got_a.arbitration_id)
for bus in (a, b, plain):
    bus.shutdown()
"""
    run = subprocess.run(["unshare", "-n", "sh", "-c", f'{SETUP} && exec "$0" -c "$1"', sys.executable, code],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["385", "385", "None", "7"]


@pytest.mark.slow
def test_an_unmodified_canopen_master_in_another_process_runs_the_drive():
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    run = subprocess.run(["unshare", "-n", "sh", "-c", f'{SETUP} && exec "$0" "$1" 3', sys.executable,
                          str(HERE / "netns_master.py")], capture_output=True, text=True, timeout=120)
    steps = [line for line in run.stdout.splitlines() if line.startswith("step:")]
    assert run.returncode == 0 and run.stdout.strip().endswith("ok"), run.stdout + run.stderr
    for stage in ("boot-up", "heartbeat", "sdo", "pdo configuration read", "mode CYCLIC SYNCHRONOUS POSITION",
                  "state OPERATION ENABLED", "streamed 200 targets", "emcy 0x8611", "fault reset and re-enabled",
                  "sync lost: emcy 0x8100", "nmt STOPPED", "drive exit 0"):
        assert any(line.startswith(f"step: {stage}") for line in steps), (stage, steps)
