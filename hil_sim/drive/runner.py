"""When the drive handles its frames: on call, in lock-step with the rig, or in a thread of its
own for an external master; and the bus it handles them on.

Both ways hand a frame to the drive's handlers through :meth:`Runner.handle`, the one place
where a frame from the bus enters the drive. It drops and counts what is not a well-formed
classic CAN frame (:func:`hil_sim.frames.frame_problem`: an identifier that is no integer in
range, a data length that does not match its DLC, ...: a transport such as ``udp_multicast``
delivers whatever a peer packed), keeps out what a CANopen node does not take (error frames,
remote frames, 29-bit identifiers: CiA 301 runs on 11-bit CAN-IDs, and a 29-bit 0x00000601 is
not the SDO request 0x601), and it is the last line of defence: an exception that escapes a
handler (a defect of the drive, never the frame's doing: each service answers bad frames itself)
is logged and reported to ``on_defect``, and the drive goes on with the next frame. The serving
thread survives any exception of its own loop the same way; should it end all the same,
:attr:`Runner.alive` says so and the owner stops (``ecam drive`` exits non-zero).
"""

from __future__ import annotations

import logging
import threading

import can

from ecam.errors import SimulationError
from hil_sim.frames import frame_problem

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
    on_defect : callable, optional
        ``on_defect(description)`` after an exception escaped a handler (logged already).
    """

    def __init__(self, bus: can.BusABC, own_bus: bool, network, on_idle, name: str,
                 on_defect=None) -> None:
        self.bus = bus
        self.own_bus = own_bus
        self.network = network
        self.on_idle = on_idle
        self.name = name
        self.on_defect = on_defect
        self.lock = threading.RLock()
        self.thread: threading.Thread | None = None
        self.running = False
        #: The bus error that ended the thread of :meth:`start` (None while it serves).
        self.failure: BaseException | None = None
        #: Received frames that were not well-formed classic CAN frames, dropped.
        self.dropped = 0

    def handle(self, msg: can.Message) -> None:
        """Hand one received frame to the network's handlers; nothing escapes."""
        problem = frame_problem(msg)
        if problem is not None:
            self._drop(problem)
            return
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        try:
            self.network.notify(msg.arbitration_id, msg.data, msg.timestamp)
        except Exception:  # noqa: BLE001 - a defect of the drive must not stop it
            self._defect(f"frame 0x{msg.arbitration_id:03X} {bytes(msg.data).hex(' ')}")

    def _drop(self, problem: str) -> None:
        self.dropped += 1
        if self.dropped == 1:
            logger.warning("%s: dropped a frame that is not a classic CAN frame (%s); further "
                           "ones are counted, not logged", self.name, problem)

    def _defect(self, what: str) -> None:
        try:
            logger.exception("drive defect while handling %s", what)
            if self.on_defect is not None:
                self.on_defect(what)
        except Exception:  # noqa: BLE001 - the report of a defect must not stop it either
            logger.exception("drive defect while reporting a defect")

    def process(self) -> int:
        """Handle every frame waiting on the bus, in order (lock-step use); return the count."""
        count = 0
        recv = self.bus.recv
        handle = self.handle
        with self.lock:
            while True:
                msg = recv(timeout=0)
                if msg is None:
                    return count
                count += 1
                handle(msg)

    def start(self, boot) -> None:
        """Call ``boot`` and handle frames in a thread until :meth:`stop`."""
        if self.thread is not None:
            raise SimulationError("the drive is already running: stop() it before start()")
        self.running = True
        self.failure = None
        with self.lock:
            boot()
        self.thread = threading.Thread(target=self._serve, name=self.name, daemon=True)
        self.thread.start()

    @property
    def alive(self) -> bool:
        """The thread of :meth:`start` serves frames (False before start, after stop, and if
        it ended: a bus failure, :attr:`failure`, or anything else)."""
        return self.thread is not None and self.thread.is_alive()

    def _serve(self) -> None:
        while self.running:
            try:
                msg = self.bus.recv(timeout=0.01)
            except (can.CanError, OSError) as exc:  # the bus itself failed: nothing to serve
                if self.running:  # not the shutdown of stop(): the owner reads it (one report)
                    self.failure = exc
                    logger.info("%s: the bus failed: %s", self.name, exc)
                break
            except Exception as exc:  # noqa: BLE001 - a transport's defect on one frame: serve on
                self._drop(f"the bus raised {type(exc).__name__} delivering it")
                continue
            with self.lock:
                if msg is not None:
                    self.handle(msg)
                try:
                    self.on_idle()
                except Exception:  # noqa: BLE001
                    self._defect("the drive's timers")

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
