"""One unmodified python-canopen master runs two CiA 402 drives that one `ecam drive` process
serves (issue 22, item 5: a whole machine over one bus from an external master).

Run by tests/test_machine_bus.py inside a private network namespace that has only loopback, so
no frame leaves the machine. Prints one ``step: ...`` line per stage reached and ``ok`` at the
end; exits non-zero at the first stage that fails.

    python3 tests/netns_machine_master.py NODE NODE

The master (canopen ``BaseNode402`` per node, ``interface="ecam_udp"``) waits for both boot-ups,
configures each drive by SDO, starts the SYNC, enables both in cyclic synchronous position and
streams each its own ramp (one +20, the other -30 counts per SYNC), reads back both positions by
TPDO, stops both by NMT and the drive process by SIGTERM.
"""

import subprocess
import sys
import threading
import time

import canopen
from canopen.profiles.p402 import BaseNode402

from hil_sim.drive import EDS_PATH
# The single-node master's helpers (this directory is on sys.path when the script runs).
from netns_master import _map_with, report_exit, step, stop_drive

CSP = "CYCLIC SYNCHRONOUS POSITION"
SYNC_PERIOD_S = 0.002
STEPS = 200


def main(ids: list[int]) -> int:
    network = canopen.Network()
    network.connect(interface="ecam_udp")
    nodes, booted = {}, {}
    for node_id in ids:
        node = BaseNode402(node_id, str(EDS_PATH))
        network.add_node(node)
        nodes[node_id] = node
        booted[node_id] = threading.Event()
        # registered before the drives start: both boot-ups come at once
        node.nmt.add_heartbeat_callback(
            lambda state, ready=booted[node_id]: ready.set() if state == 0 else None)
    drive = subprocess.Popen([sys.executable, "-m", "ecam.app", "drive", "--interface",
                              "udp_multicast", "--node-id", ",".join(str(n) for n in ids)],
                             stdout=subprocess.PIPE, text=True)
    try:
        for node_id, ready in booted.items():
            assert ready.wait(15.0), f"no boot-up from node {node_id}"
        step(f"boot-up of nodes {', '.join(str(n) for n in ids)}")
        for node_id, node in nodes.items():
            assert node.sdo[0x1000].raw == 0x00020192, node_id
            node.sdo[0x60C2][1].raw = 1  # 1 ms per SYNC (0x60C2 = 1 x 10^-3 s)
            node.sdo[0x60C2][2].raw = -3
            node.setup_402_state_machine()  # reads the PDO configuration by SDO
            node.rpdo.read()
        step("sdo and pdo configuration of each node")
        for node in nodes.values():
            node.nmt.state = "OPERATIONAL"
        network.sync.start(SYNC_PERIOD_S)
        starts, maps = {}, {}
        for node_id, node in nodes.items():
            node.op_mode = CSP
            starts[node_id] = node.sdo[0x6064].raw
            maps[node_id] = _map_with(node.rpdo, 0x607A)
            maps[node_id][0x607A].raw = starts[node_id]
            maps[node_id].transmit()
            node.state = "OPERATION ENABLED"
        step(f"states {[nodes[n].state for n in ids]}")
        slopes = {node_id: (20, -30)[i % 2] for i, node_id in enumerate(ids)}
        for k in range(STEPS):
            for node_id, pdo_map in maps.items():
                pdo_map[0x607A].raw = starts[node_id] + slopes[node_id] * k
                pdo_map.transmit()
            time.sleep(SYNC_PERIOD_S)
        time.sleep(10 * SYNC_PERIOD_S)
        for node_id, node in nodes.items():
            actual = node.tpdo_values.get(0x6064)
            goal = starts[node_id] + slopes[node_id] * (STEPS - 1)
            step(f"node {node_id} streamed {STEPS} targets, position by TPDO {actual} "
                 f"(target {goal})")
            assert actual is not None and abs(actual - goal) < 1000, (node_id, actual, goal)
            statusword = node.sdo[0x6041].raw
            assert statusword & 0x6F == 0x27, f"node {node_id} statusword 0x{statusword:04X}"
        step("both drives followed their own targets")
        network.sync.stop()
        for node in nodes.values():
            node.nmt.state = "STOPPED"
    finally:
        network.disconnect()
        out = stop_drive(drive)
        if out is None:
            return 1
    return report_exit(drive, out)


if __name__ == "__main__":
    sys.exit(main([int(n) for n in sys.argv[1:]] or [5, 6]))
