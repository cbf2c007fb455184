"""The virtual drive as a network node: `ecam drive --interface udp_multicast` in one process, an
unmodified canopen BaseNode402 master in another, inside a private network namespace with only
loopback, so no frame leaves the machine (tests/netns_master.py). The master connects with
`interface="ecam_udp"` and no frame filters, or with plain `udp_multicast` and the receive
filters the README gives for it; the README's own master script and namespace command, as
written; and the transport itself: why `ecam_udp` exists (plain udp_multicast hands a sender its
own frames), that a datagram which is no frame does not silence a node, and that a burst of
frames a busy process has not read yet is not lost."""

import os
import re
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


def test_the_echo_free_bus_holds_a_burst_of_frames_its_reader_is_not_ready_for():
    """A drive process the scheduler leaves waiting while SYNCs arrive must find them all when
    it runs again: 3000 frames (0.75 s of a drive's traffic at a 1 kHz SYNC, its own frames
    looped back included) sent while nobody reads are all received. With the system's default
    receive buffer (208 KiB) only the first 256 or so are."""
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    code = """
import can
receiver, sender = can.Bus(interface="ecam_udp"), can.Bus(interface="ecam_udp")
for k in range(3000):
    sender.send(can.Message(arbitration_id=0x80, data=[k & 0xFF], is_extended_id=False))
got = []
while (msg := receiver.recv(0.5)) is not None:
    got.append(msg.data[0])
print(len(got), got == [k & 0xFF for k in range(3000)])
receiver.shutdown(); sender.shutdown()
"""
    run = subprocess.run(["unshare", "-n", "sh", "-c", f'{SETUP} && exec "$0" -c "$1"',
                          sys.executable, code], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["3000", "True"]


STAGES = ("boot-up", "heartbeat", "sdo", "pdo mapping written by sdo", "pdo configuration read",
          "mode CYCLIC SYNCHRONOUS POSITION", "state OPERATION ENABLED", "streamed 200 targets",
          "drive time")
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


def _readme_block(heading: str, language: str, contains: str) -> str:
    """The first ```language block under the network drive page's ``heading`` (moved there from
    the README) that contains ``contains``."""
    text = (HERE.parent / "docs" / "howto" / "network-drive.md").read_text()
    section = text[text.index(heading):]
    for block in re.findall(rf"^```{language}\n(.*?)^```", section, flags=re.S | re.M):
        if contains in block:
            return block
    raise LookupError(f"docs/howto/network-drive.md: no {language} block with {contains!r} under {heading!r}")


@pytest.mark.slow
def test_the_readme_master_script_and_namespace_command_run_as_written(tmp_path):
    """The network drive page's master script and its `unshare -n` command, verbatim (the
    page's command is written for root, as the test runs it), with `ecam` on PATH running this
    checkout. The drive starts at 0 counts; the script streams 1000 targets of 20 counts."""
    reason = _namespace_unavailable()
    if reason:
        pytest.skip(reason)
    heading = "## A master in another process on the same machine"
    (tmp_path / "master.py").write_text(_readme_block(heading, "python", "BaseNode402"))
    command = _readme_block(heading, "bash", "unshare -n")
    assert command.startswith("unshare -n sh -c "), command  # as root, as the page says
    ecam = tmp_path / "bin" / "ecam"
    ecam.parent.mkdir()
    ecam.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m ecam.app "$@"\n')
    ecam.chmod(0o755)
    python_path = [str(HERE.parent)] + [p for p in [os.environ.get("PYTHONPATH")] if p]
    env = {**os.environ, "PATH": f"{ecam.parent}{os.pathsep}{os.environ['PATH']}",
           "PYTHONPATH": os.pathsep.join(python_path)}
    run = subprocess.run(["sh", "-c", command], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    found = re.search(r"^position (-?\d+) statusword 0x([0-9a-f]+)$", run.stdout, flags=re.M)
    assert found, run.stdout + run.stderr
    position, statusword = int(found[1]), int(found[2], 16)
    assert statusword & 0x6F == 0x27, hex(statusword)  # CiA 402: OPERATION ENABLED
    assert abs(position - 20 * 999) < 1000, position
    assert run.stdout.strip().splitlines()[-1] == "virtual drive stopped", run.stdout
