"""NMT slave: the drive's NMT state, the commands of the NMT master, boot-up and heartbeat.

Written here rather than taken from canopen: canopen's slave produces the heartbeat from a timer
thread, and the rig needs it on the drive's own (simulated) clock.
"""

from __future__ import annotations

import math

from hil_sim.drive.cia402 import INITIALISING, NMT_COMMANDS, PRE_OPERATIONAL
from hil_sim.drive.objects import HEARTBEAT_COB_ID

#: Node id 0 in an NMT command addresses every node (CiA 301).
ALL_NODES = 0


class NmtSlave:
    """NMT state and heartbeat producer of one node.

    Parameters
    ----------
    network : canopen.Network
        Where boot-up and heartbeat frames go.
    node_id : int
        The node's id.
    clock : callable
        The drive's time now [s], for the heartbeat schedule.
    reset : callable
        ``reset(kind)`` for an NMT reset command, ``kind`` "application" or "communication";
        the boot-up follows it.
    entered : callable
        ``entered(state)`` after an NMT command that changes the state without a reset.
    """

    def __init__(self, network, node_id: int, clock, reset, entered) -> None:
        self.network = network
        self.node_id = node_id
        self.clock = clock
        self._reset = reset
        self._entered = entered
        self.state = INITIALISING
        self.heartbeat_period_s = 0.0  # 0: no heartbeat
        self.next_heartbeat = math.inf  # drive time of the next heartbeat [s]

    def boot(self) -> None:
        """Initialise, send the boot-up message, enter PRE-OPERATIONAL."""
        self.state = INITIALISING
        # CiA 301: the boot-up message is a heartbeat that reports INITIALISING.
        self.network.send_message(HEARTBEAT_COB_ID + self.node_id, bytes([INITIALISING]))
        self.state = PRE_OPERATIONAL
        self.next_heartbeat = self.clock() + self.heartbeat_period_s

    def on_command(self, can_id, data, timestamp) -> None:
        """Network callback for the NMT COB-ID."""
        if len(data) < 2 or data[1] not in (ALL_NODES, self.node_id):
            return
        command = NMT_COMMANDS.get(data[0])
        if command is None:
            return
        state, reset = command
        if reset is not None:
            self._reset(reset)
            self.boot()
        else:
            self.state = state
            self._entered(state)

    def set_heartbeat_period(self, period_s: float) -> None:
        """A new producer heartbeat time (0x1017), counted from now."""
        self.heartbeat_period_s = period_s
        self.next_heartbeat = self.clock() + period_s

    def reset_heartbeat(self, period_s: float) -> None:
        """The producer heartbeat time after a reset: the first heartbeat follows the boot-up."""
        self.heartbeat_period_s = period_s
        self.next_heartbeat = math.inf

    def service_heartbeat(self) -> None:
        """Send the heartbeat if it is due."""
        period = self.heartbeat_period_s
        if period <= 0.0 or self.state == INITIALISING:
            return
        now = self.clock()
        if now + 1e-12 >= self.next_heartbeat:
            self.network.send_message(HEARTBEAT_COB_ID + self.node_id, bytes([self.state]))
            self.next_heartbeat += period
            if self.next_heartbeat <= now:  # fell far behind (wall clock): resynchronise
                self.next_heartbeat = now + period
