"""`ecam drive` as a process (issue 13, item 1): it stops cleanly on SIGINT and SIGTERM (exit 0,
its last line printed, nothing on stderr), and a transport that cannot be opened or fails while
the drive runs is one line on stderr and exit status 2.

The processes here use the in-process `virtual` bus, so no frame leaves them; the cross-process
runs over udp_multicast are in tests/test_drive_network.py (inside a private network namespace).
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading

import can
import pytest
from can.interfaces.virtual import VirtualBus

from ecam.app import cli, drive_command

BANNER = "virtual CiA 402 drive, node 3, on virtual channel 'ecam'"


def _start_drive() -> tuple[subprocess.Popen, str]:
    process = subprocess.Popen([sys.executable, "-m", "ecam.app", "drive", "--interface", "virtual",
                                "--node-id", "3"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = process.stdout.readline()  # printed once its signal handlers are set
    assert first.startswith(BANNER), first + process.stderr.read()
    return process, first


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_the_drive_process_stops_cleanly_on_a_signal(signum):
    process, banner = _start_drive()
    # Whoever starts `ecam drive` on the in-process bus learns at once that no other process
    # can reach it.
    assert "only a master in this same Python process reaches it" in banner
    process.send_signal(signum)
    try:
        out, err = process.communicate(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err
    assert out.strip().splitlines()[-1] == "virtual drive stopped"
    assert err == ""


def test_a_transport_that_cannot_be_opened_is_one_line_and_exit_2(capsys):
    # 1.2.3.4 is no multicast group: joining it fails before anything is sent.
    status = cli.main(["drive", "--interface", "udp_multicast", "--channel", "1.2.3.4"])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1
    assert err.startswith("ecam: error: interface 'udp_multicast' channel '1.2.3.4' cannot be opened")


class _FailingBus(VirtualBus):
    """A bus whose receive fails after a few polls, as a socket does when its interface goes."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.polls = 0

    def _recv_internal(self, timeout):
        self.polls += 1
        if self.polls > 3:
            raise can.CanOperationError("the interface went down")
        return super()._recv_internal(timeout)


def test_a_bus_that_fails_while_the_drive_runs_is_one_line_and_exit_2(monkeypatch, capsys):
    bus = _FailingBus(channel="test-drive-command-failing")
    monkeypatch.setattr(drive_command, "open_drive_bus", lambda interface, channel: (bus, "ecam"))
    done = []
    worker = threading.Thread(target=lambda: done.append(cli.main(["drive", "--interface", "socketcan"])))
    worker.start()
    worker.join(10.0)
    assert done == [2]
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("ecam: error: interface 'socketcan' channel 'ecam' failed while the drive "
                          "ran: the interface went down")


def test_the_interface_choices_are_the_drive_commands_table():
    """`--interface` takes what drive_command can open (one table), and reading that table
    loads no CAN stack, so `ecam laws` still starts without python-can."""
    import argparse

    parser = argparse.ArgumentParser()
    cli.add_drive_arguments(parser)  # as `ecam drive` and `hil-sim drive` both build theirs
    choices = next(a.choices for a in parser._actions if "--interface" in a.option_strings)
    assert tuple(choices) == drive_command.INTERFACES == tuple(drive_command.DEFAULT_CHANNELS)
    assert set(drive_command._REACH) == set(drive_command.INTERFACES)
    from hil_sim.udp_bus import DEFAULT_GROUP

    for interface in ("udp_multicast", "ecam_udp"):  # python-can's group, looked up when opened
        assert drive_command.DEFAULT_CHANNELS[interface] is None
    assert drive_command.open_drive_bus("virtual", None) == (None, "ecam")
    code = ("import sys, ecam.app.cli; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('can', 'canopen')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    assert DEFAULT_GROUP == "239.74.163.2"  # what `--channel`'s help names as the default
