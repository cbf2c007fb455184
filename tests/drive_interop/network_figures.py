"""The figures of the drive as a network node (issue 13): `ecam drive --interface udp_multicast`
in a subprocess, an unmodified canopen BaseNode402 master here (interface ``ecam_udp``, no frame
filters), and a passive listener bus that timestamps every SYNC and TPDO1 (the kernel's receive
timestamps, one clock for both).

Run it inside a private network namespace with only loopback, so no frame leaves the machine:

    unshare -n sh -c 'ip link set lo up && ip route add 224.0.0.0/4 dev lo &&
        exec python3 tests/drive_interop/network_figures.py [CYCLES]'

It enables the drive in CSP with a 1 ms SYNC, streams CYCLES targets (1000 by default) on
absolute 1 ms deadlines as a master keeps its cycle, stops the SYNC, waits until the drive has
answered every SYNC, and prints: targets per second, the SYNC period (mean, median, max), the
latency from each SYNC to the TPDO1 the drive sends for it (median, 90th percentile; the k-th
TPDO1 answers the k-th SYNC), SYNCs against TPDO1s, the datagrams the kernel dropped at each
socket for want of receive buffer, and how the drive stopped on SIGINT. Not a test: the figures
depend on the machine and its load.
"""

import os
import signal
import statistics
import subprocess
import sys
import threading
import time

import can
import canopen
from canopen.profiles.p402 import BaseNode402

from hil_sim.drive import EDS_PATH

NODE = 3
PERIOD_S = 0.001
SYNC, TPDO1, RPDO2 = 0x080, 0x180 + NODE, 0x300 + NODE


def main(cycles: int) -> int:
    drive = subprocess.Popen([sys.executable, "-m", "ecam.app", "drive", "--interface",
                              "udp_multicast", "--node-id", str(NODE)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    listener = can.Bus(interface="ecam_udp")
    frames: list[tuple[int, float]] = []
    listening = threading.Event()
    listening.set()

    def listen() -> None:
        while listening.is_set():
            msg = listener.recv(0.1)
            if msg is not None:
                frames.append((msg.arbitration_id, msg.timestamp))

    reader = threading.Thread(target=listen)
    reader.start()
    network = canopen.Network()
    network.connect(interface="ecam_udp")
    try:
        node = BaseNode402(NODE, str(EDS_PATH))
        network.add_node(node)
        node.nmt.wait_for_heartbeat(10.0)
        node.setup_402_state_machine()
        node.nmt.state = "OPERATIONAL"
        network.sync.start(PERIOD_S)
        node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
        node.state = "OPERATION ENABLED"
        targets = node.rpdo[2]
        start = node.sdo[0x6064].raw
        frames.clear()
        began = time.perf_counter()
        for k in range(cycles):
            targets["Target position"].raw = start + 20 * k
            targets["Velocity offset"].raw = 0
            targets.transmit()
            time.sleep(max(0.0, began + (k + 1) * PERIOD_S - time.perf_counter()))
        elapsed = time.perf_counter() - began
        network.sync.stop()
        seen = -1
        while seen != len(frames):  # until the drive has answered every SYNC it got
            seen = len(frames)
            time.sleep(0.3)
        drops = _socket_drops(drive.pid)
        position = node.tpdo_values[0x6064]
        node.nmt.state = "STOPPED"
    finally:
        network.disconnect()
        listening.clear()
        reader.join()
        listener.shutdown()
        drive.send_signal(signal.SIGINT)
        out, err = drive.communicate(timeout=10)

    syncs = [t for i, t in frames if i == SYNC]
    # A TPDO1 that answers a SYNC sent before the count started is not one of them.
    tpdos = [t for i, t in frames if i == TPDO1 and t > syncs[0]]
    rpdos = sum(1 for i, _ in frames if i == RPDO2)
    periods = [b - a for a, b in zip(syncs, syncs[1:])]
    print(f"targets: {cycles} in {elapsed:.3f} s, {cycles / elapsed:.0f} per second "
          f"({rpdos} RPDO2 frames on the bus)")
    print(f"SYNC period: mean {statistics.mean(periods) * 1e3:.3f} ms, median "
          f"{statistics.median(periods) * 1e3:.3f} ms, max {max(periods) * 1e3:.3f} ms "
          f"over {len(syncs)} SYNCs")
    print(f"SYNCs {len(syncs)}, TPDO1s {len(tpdos)}; datagrams dropped: {drops}")
    if len(syncs) == len(tpdos) and all(t > s for s, t in zip(syncs, tpdos)):
        latency = sorted(t - s for s, t in zip(syncs, tpdos))
        print(f"TPDO1 after its SYNC: median {statistics.median(latency) * 1e3:.3f} ms, "
              f"90th percentile {latency[int(0.9 * len(latency))] * 1e3:.3f} ms")
    else:
        print("TPDO1 latency: not measured, the TPDO1s do not pair with the SYNCs")
    print(f"position {position}, last target {start + 20 * (cycles - 1)}")
    last = out.strip().splitlines()[-1] if out.strip() else ""
    print(f"drive: exit {drive.returncode} on SIGINT, last line {last!r}, stderr {err.strip()!r}")
    return 0


def _socket_drops(drive_pid: int) -> str:
    """Datagrams the kernel dropped at the drive's and this process's UDP sockets (the last
    column of /proc/net/udp, this namespace's sockets only)."""
    fd_dir = f"/proc/{drive_pid}/fd"
    drive_inodes = {os.stat(f"{fd_dir}/{fd}").st_ino for fd in os.listdir(fd_dir)
                    if os.readlink(f"{fd_dir}/{fd}").startswith("socket:")}
    counts = {"drive": 0, "master and listener": 0}
    with open("/proc/net/udp") as table:
        for line in table.read().splitlines()[1:]:
            fields = line.split()
            owner = "drive" if int(fields[9]) in drive_inodes else "master and listener"
            counts[owner] += int(fields[-1])
    return ", ".join(f"{owner} {count}" for owner, count in counts.items())


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 1000))
