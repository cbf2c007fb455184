"""When the drive handles its frames: on call, in lock-step with the rig, or in a thread of its
own for an external master; and the bus it handles them on."""

from __future__ import annotations

import logging
import threading

import can

from hil_sim.bus import pump

logger = logging.getLogger(__name__)


class Runner:
    """Feeds the frames of a bus to a network, on call or from a thread.

    One re-entrant lock serialises both ways with each other (and with the boot), so a frame is
    never handled while another is.

    Parameters
    ----------
    bus : can.BusABC
        The drive's bus.
    own_bus : bool
        The drive opened the bus, so :meth:`close` shuts it down.
    network : canopen.Network
        Receives the frames.
    on_idle : callable
        Called after every frame or receive time-out in the thread (the heartbeat).
    name : str
        Name of the thread.
    """

    def __init__(self, bus: can.BusABC, own_bus: bool, network, on_idle, name: str) -> None:
        self.bus = bus
        self.own_bus = own_bus
        self.network = network
        self.on_idle = on_idle
        self.name = name
        self.lock = threading.RLock()
        self.thread: threading.Thread | None = None
        self.running = False

    def process(self) -> int:
        """Handle every frame waiting on the bus, in order (lock-step use); return the count."""
        with self.lock:
            return pump(self.bus, self.network)

    def start(self, boot) -> None:
        """Call ``boot`` and handle frames in a thread until :meth:`stop`."""
        if self.thread is not None:
            raise RuntimeError("the drive is already running")
        self.running = True
        with self.lock:
            boot()
        self.thread = threading.Thread(target=self._serve, name=self.name, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while self.running:
            try:
                msg = self.bus.recv(timeout=0.01)
            except can.CanError:
                break
            with self.lock:
                if msg is not None and not (msg.is_error_frame or msg.is_remote_frame):
                    try:
                        self.network.notify(msg.arbitration_id, msg.data, msg.timestamp)
                    except Exception:  # a bad frame must not stop the drive
                        logger.exception("frame 0x%03X", msg.arbitration_id)
                self.on_idle()

    def stop(self) -> None:
        """Stop the thread of :meth:`start` and release the bus if the drive opened it."""
        self.running = False
        if self.thread is not None:
            self.thread.join(timeout=5.0)
            self.thread = None
        self.close()

    def close(self) -> None:
        """Release the bus if the drive opened it."""
        if self.own_bus and self.bus is not None:
            self.bus.shutdown()
            self.bus = None
