"""An unmodified python-canopen CiA 402 master in one process, the virtual drive in another.

Run by tests/test_drive_network.py inside a private network namespace that has only loopback, so
no frame leaves the machine. Prints one ``step: ...`` line per stage reached and ``ok`` at the
end; exits non-zero at the first stage that fails. The master maps TPDO2 by SDO (velocity actual
value and position on every SYNC), sets the interpolation period to 1 ms and sends SYNC every
2 ms, so the velocity it reads shows the drive's time runs one interpolation period per SYNC.

    python3 tests/netns_master.py NODE_ID [ecam_udp | udp_multicast]

The master connects with ``interface="ecam_udp"`` (python-can's udp_multicast without the
sender's own frames; no frame filters), or with plain ``udp_multicast`` and the receive filters
the README gives for it (a master on plain udp_multicast hears its own RPDOs back, and canopen
then stops sending the controlword): the second run stops after streaming.
"""

import signal
import statistics
import subprocess
import sys
import time

import canopen
from canopen.profiles.p402 import BaseNode402

from hil_sim.drive import EDS_PATH

CSP = "CYCLIC SYNCHRONOUS POSITION"
GROUP = "239.74.163.2"  # the drive's default group (python-can's IPv4 default)
SYNC_PERIOD_S = 0.002
INTERPOLATION_PERIOD_MS = 1  # 0x60C2 the master writes: the drive's time per SYNC
FOLLOWING_ERROR_EMCY = 0x8611  # CiA 402: following error


def step(text):
    print(f"step: {text}", flush=True)


def stop_drive(drive) -> str | None:
    """SIGTERM to the drive process and its output; None (said) when it did not stop."""
    drive.send_signal(signal.SIGTERM)
    try:
        return drive.communicate(timeout=10)[0]
    except subprocess.TimeoutExpired:
        drive.kill()
        drive.communicate()
        print("drive did not stop on SIGTERM", flush=True)
        return None


def report_exit(drive, out: str) -> int:
    """The stopped drive's exit status and last line; the status is the script's."""
    step(f"drive exit {drive.returncode}: {out.strip().splitlines()[-1] if out.strip() else ''}")
    print("ok" if drive.returncode == 0 else "drive failed", flush=True)
    return drive.returncode


def master_filters(node_id: int) -> list[dict]:
    """What a master on plain udp_multicast receives: the drive's EMCY, TPDOs, SDO responses and
    heartbeat, never the COB-IDs it sends itself (NMT, SYNC, RPDOs, SDO requests)."""
    return [{"can_id": function + node_id, "can_mask": 0x7FF}
            for function in (0x080, 0x180, 0x280, 0x380, 0x480, 0x580, 0x700)]


def main(node_id: int, interface: str = "ecam_udp") -> int:
    network = canopen.Network()
    if interface == "ecam_udp":
        network.connect(interface="ecam_udp")  # the master's own bus: no frame filters
    else:
        network.connect(interface="udp_multicast", channel=GROUP, can_filters=master_filters(node_id))
    drive = subprocess.Popen([sys.executable, "-m", "ecam.app", "drive", "--interface", "udp_multicast",
                              "--node-id", str(node_id)], stdout=subprocess.PIPE, text=True)
    try:
        node = BaseNode402(node_id, str(EDS_PATH))
        network.add_node(node)
        node.nmt.wait_for_bootup(15.0)
        step("boot-up")
        node.nmt.wait_for_heartbeat(5.0)
        step(f"heartbeat {node.nmt.state}")
        assert node.sdo[0x1000].raw == 0x00020192
        step("sdo")
        configure_tpdo2(node)
        node.setup_402_state_machine()  # reads the PDO configuration by SDO
        node.rpdo.read()
        step("pdo configuration read")
        node.nmt.state = "OPERATIONAL"
        network.sync.start(SYNC_PERIOD_S)
        node.op_mode = CSP
        step(f"mode {node.op_mode}")
        position = node.sdo[0x6064].raw
        node.rpdo[0x607A].raw = position
        node.state = "OPERATION ENABLED"
        step(f"state {node.state}")

        target_map = _map_with(node.rpdo, 0x607A)
        tpdo2 = []  # (velocity, position), one per SYNC
        node.tpdo[2].add_callback(lambda pdo: tpdo2.append((pdo[0x606C].raw, pdo[0x6064].raw)))
        for k in range(200):
            target_map[0x607A].raw = position + 20 * k
            target_map.transmit()
            time.sleep(SYNC_PERIOD_S)
            if k == 100:  # the second half of the ramp, past the start's transient
                first = len(tpdo2)
        ramp = tpdo2[first:len(tpdo2)]
        time.sleep(10 * SYNC_PERIOD_S)
        actual = node.tpdo_values.get(0x6064)
        step(f"streamed 200 targets, position by TPDO {actual}")
        assert actual is not None and abs(actual - (position + 20 * 199)) < 1000, actual
        check_drive_time(ramp)
        if interface == "ecam_udp":
            fault_reset_and_sync_loss(network, node, target_map)

        node.nmt.state = "STOPPED"
        time.sleep(0.2)
        frames = len(tpdo2)
        # The drive's own word: its next heartbeat (0x1017, 1 s) reports STOPPED, and in STOPPED
        # it sends no PDO (CiA 301), though the SYNC may still run.
        reported = node.nmt.wait_for_heartbeat(2.5)
        assert reported == "STOPPED" and len(tpdo2) == frames, (reported, len(tpdo2) - frames)
        step(f"nmt {reported} by heartbeat, no TPDO since")
    finally:
        network.disconnect()
        out = stop_drive(drive)
        if out is None:
            return 1
    return report_exit(drive, out)


def configure_tpdo2(node) -> None:
    """The master sets up its process data by SDO, in PRE-OPERATIONAL: TPDO2 carries the
    velocity actual value and the position on every SYNC, and the interpolation period is 1 ms
    (0x60C2 = 1 x 10^-3 s), half the SYNC spacing the master keeps on the wall clock."""
    node.sdo[0x60C2][1].raw = INTERPOLATION_PERIOD_MS
    node.sdo[0x60C2][2].raw = -3
    node.tpdo.read()
    tpdo2 = node.tpdo[2]
    tpdo2.clear()
    tpdo2.add_variable(0x606C)
    tpdo2.add_variable(0x6064)
    tpdo2.trans_type = 1
    tpdo2.enabled = True
    tpdo2.save()
    node.tpdo[2].read()  # back from the drive by SDO
    mapped = [(var.index, var.length) for var in node.tpdo[2].map]
    assert mapped == [(0x606C, 32), (0x6064, 32)], mapped
    assert node.tpdo[2].trans_type == 1 and node.tpdo[2].enabled, node.tpdo[2].trans_type
    step(f"pdo mapping written by sdo: TPDO2 0x{node.tpdo[2].cob_id:03X} = 0x606C, 0x6064 "
         "on every SYNC")


def check_drive_time(frames: list[tuple[int, int]]) -> None:
    """The drive's time is its SYNC count (issue 13, item 2). TPDO2 (mapped by the master) comes
    once per SYNC with the velocity actual value and the position: the counts the position moved
    per frame, over the interpolation period (1 ms), is the speed in the drive's time, and the
    drive's own velocity agrees with it. Had the drive run on the wall clock, its velocity would
    be half that, the master sending a SYNC every 2 ms."""
    (_, start), (_, end) = frames[0], frames[-1]
    per_period = (end - start) / (len(frames) - 1) / (INTERPOLATION_PERIOD_MS * 1e-3)
    velocity = statistics.mean(v for v, _ in frames[1:])
    step(f"drive time: {len(frames)} TPDO2 frames, velocity actual {velocity:.0f} counts/s, the "
         f"position's {per_period:.0f} counts/s at 1 ms per SYNC ({per_period / 2:.0f} at 2 ms)")
    # 10 %: the speed estimate's filter lags an uneven ramp (the master's targets come on its
    # own wall-clock loop, not on the SYNC); the two hypotheses differ by a factor of 2.
    assert abs(velocity - per_period) < 0.1 * per_period, (velocity, per_period)


def fault_reset_and_sync_loss(network, node, target_map) -> None:
    """A following-error fault with its EMCY, fault reset and re-enable, then the SYNC stops."""
    position = node.sdo[0x6064].raw
    node.emcy.reset()
    target_map[0x607A].raw = position + 2**29  # far beyond the following-error window
    target_map.transmit()
    emcy = node.emcy.wait(FOLLOWING_ERROR_EMCY, timeout=5.0)
    assert emcy is not None, "no following-error EMCY"
    # CiA 402: FAULT REACTION ACTIVE passes to FAULT by itself once the reaction is done
    # (transition 14); a fault reset is accepted in FAULT only.
    deadline = time.monotonic() + 2.0
    statusword = node.sdo[0x6041].raw
    while statusword & 0x4F != 0x08 and time.monotonic() < deadline:
        time.sleep(SYNC_PERIOD_S)
        statusword = node.sdo[0x6041].raw
    assert statusword & 0x4F == 0x08, f"statusword 0x{statusword:04X} is not FAULT"
    time.sleep(5 * SYNC_PERIOD_S)  # the statusword TPDO catches up
    step(f"emcy 0x{emcy.code:04X}, statusword 0x{statusword:04X} (fault)")
    position = node.sdo[0x6064].raw
    target_map[0x607A].raw = position
    target_map.transmit()
    node.reset_from_fault()
    node.state = "OPERATION ENABLED"
    position = node.sdo[0x6064].raw  # re-enabled where the axis is: stream on from there
    for k in range(50):
        target_map[0x607A].raw = position + 20 * k
        target_map.transmit()
        time.sleep(SYNC_PERIOD_S)
    time.sleep(10 * SYNC_PERIOD_S)
    statusword = node.sdo[0x6041].raw
    assert statusword & 0x6F == 0x27, f"statusword 0x{statusword:04X} after re-enable"
    step(f"fault reset and re-enabled, statusword 0x{statusword:04X}, following again")

    # SYNC supervision: 0x1006 arms it, 0x6007 = 1 (fault) is the reaction to a lost SYNC.
    node.sdo[0x1006].raw = int(SYNC_PERIOD_S * 1e6)
    node.emcy.reset()
    network.sync.stop()
    emcy = node.emcy.wait(0x8100, timeout=2.0)
    assert emcy is not None, "no EMCY when the SYNC stopped"
    deadline = time.monotonic() + 2.0
    statusword = node.sdo[0x6041].raw
    while statusword & 0x4F != 0x08 and time.monotonic() < deadline:
        time.sleep(SYNC_PERIOD_S)
        statusword = node.sdo[0x6041].raw
    assert statusword & 0x4F == 0x08, f"statusword 0x{statusword:04X} after the SYNC stopped"
    step(f"sync lost: emcy 0x{emcy.code:04X}, statusword 0x{statusword:04X} (fault)")


def _map_with(maps, index):
    for pdo_map in maps.values():
        if any(var.index == index for var in pdo_map.map):
            return pdo_map
    raise LookupError(f"no RPDO maps 0x{index:04X}")


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 3, *sys.argv[2:3]))
