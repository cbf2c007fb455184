"""`ecam drive` (and `hil-sim drive`): the virtual CiA 402 drive as a process of its own, for a
master under test in another process.

It runs until Ctrl-C, SIGINT or SIGTERM (a service manager, `kill`), then shuts its bus down
and exits 0. Exit status 2, one line on stderr, for bad input, a transport that cannot be
opened, a bus that fails while the drive runs (python-can raised from ``recv``), or a serving
thread that ended for any other reason: a drive that answers nothing must not look alive.

A shell starts a background job (`ecam drive ... &` in a script) with SIGINT ignored, as it does
for every program; the drive keeps that, so in a script stop it with SIGTERM (`kill $pid`).
"""

from __future__ import annotations

import argparse
import errno
import signal
import threading
import time

from ecam import validate
from ecam.errors import EcamError

# The CAN stack and the drive are imported in the functions that run the drive: the command line
# reads the table of transports below (its --interface choices) for every command it parses.

#: Transports and their default channels (None: python-can's IPv4 multicast group,
#: ``hil_sim.udp_bus.DEFAULT_GROUP``, 239.74.163.2). The in-process `virtual` bus reaches only
#: masters in this process; the others reach other processes. `ecam_udp` is `udp_multicast`
#: without the sender's own frames (:mod:`hil_sim.udp_bus`); the drive always opens
#: `udp_multicast` that way (same wire format and groups, so masters on either interface reach
#: it). The order is the command line's (its default first).
DEFAULT_CHANNELS = {"udp_multicast": None, "ecam_udp": None, "socketcan": "vcan0", "virtual": "ecam"}
#: The transports `ecam drive --interface` takes.
INTERFACES = tuple(DEFAULT_CHANNELS)
# What a multicast socket fails with when no interface reaches the group.
_NO_ROUTE = (errno.ENODEV, errno.ENETUNREACH)

#: What a master needs to reach the drive, by transport (printed when the drive starts).
_REACH = {
    "virtual": "in-process bus: only a master in this same Python process reaches it; for "
               "another process use --interface udp_multicast or socketcan",
    "udp_multicast": "python-can masters connect with interface='ecam_udp'",
    "ecam_udp": "python-can masters connect with interface='ecam_udp'",
    "socketcan": "any SocketCAN master on this interface reaches it",
}


def open_drive_bus(interface: str, channel: str | None):
    """The bus the drive runs on.

    Parameters
    ----------
    interface : {"virtual", "udp_multicast", "ecam_udp", "socketcan"}
    channel : str or None
        None: the transport's default (:data:`DEFAULT_CHANNELS`).

    Returns
    -------
    (can.BusABC or None, str)
        The bus (None for the in-process virtual bus, which the drive opens itself) and the
        channel.

    Raises
    ------
    EcamError
        The transport cannot be opened (message names interface, channel and why).
    """
    import can

    from hil_sim.udp_bus import DEFAULT_GROUP, EchoFreeUdpMulticastBus

    channel = channel or DEFAULT_CHANNELS[interface] or DEFAULT_GROUP
    if interface == "virtual":
        return None, channel
    try:
        if interface in ("udp_multicast", "ecam_udp"):
            return EchoFreeUdpMulticastBus(channel=channel), channel
        return can.Bus(interface=interface, channel=channel), channel
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        cause = exc.__cause__ or exc.__context__ or exc
        if interface in ("udp_multicast", "ecam_udp") and getattr(cause, "errno", None) in _NO_ROUTE:
            # ENODEV/ENETUNREACH: the kernel has no interface to send the group to (a network
            # namespace with only loopback, a machine without a default route).
            raise EcamError(f"interface {interface!r} channel {channel!r} cannot be opened: no route to "
                            f"the multicast group ({cause.strerror}); add one, as root: ip route add "
                            "224.0.0.0/4 dev lo (this machine only) or dev <your LAN interface>") from None
        raise EcamError(f"interface {interface!r} channel {channel!r} cannot be opened: {exc}") from None


def drive_command(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Run a virtual drive until Ctrl-C, SIGINT or SIGTERM (or until ``stop`` is set).

    Parameters
    ----------
    args : argparse.Namespace
        ``interface``, ``channel``, ``node_id``, ``heartbeat_ms``, ``scene`` (see
        :func:`ecam.app.cli.add_drive_arguments`).
    stop : threading.Event, optional
        Set by the caller to stop the drive (tests run it in a thread).

    Returns
    -------
    int
        0 once stopped.

    Raises
    ------
    EcamError
        The transport cannot be opened, or its bus failed while the drive ran.
    """
    import can

    from hil_sim.drive import VirtualDrive
    from hil_sim.rig import drive_for_scene

    if args.node_id is not None:  # before the bus opens: a wrong id is bad input, not a bus error
        validate.integer("node_id", args.node_id, minimum=1, maximum=127)
    bus, channel = open_drive_bus(args.interface, args.channel)
    try:
        if args.scene is not None:
            drive = drive_for_scene(args.scene, channel=channel, bus=bus, node_id=args.node_id,
                                    heartbeat_ms=args.heartbeat_ms)
        else:
            drive = VirtualDrive(channel=channel, node_id=1 if args.node_id is None else args.node_id,
                                 bus=bus, heartbeat_ms=args.heartbeat_ms)
    except BaseException:
        if bus is not None:
            bus.shutdown()
        raise
    stop = stop or threading.Event()
    signalled, restore = _stop_on_signals()
    print(f"virtual CiA 402 drive, node {drive.node_id}, on {args.interface} channel "
          f"{channel!r} ({_REACH[args.interface]}); Ctrl-C or SIGTERM stops it", flush=True)
    deaf = False
    try:
        drive.start()
        # Polled, not waited on: the signal handler takes no lock (see _stop_on_signals), and
        # Event.is_set() takes none either.
        while not (stop.is_set() or signalled):
            if drive.failure is not None:
                break
            if not drive.runner.alive:
                deaf = True
                break
            time.sleep(_POLL_S)
    except KeyboardInterrupt:
        pass  # SIGINT before its handler was set, or where none could be set
    except (can.CanError, OSError) as exc:  # the boot-up could not be sent
        raise EcamError(f"interface {args.interface!r} channel {channel!r} failed: {exc}") from None
    finally:
        drive.stop()
        if bus is not None:
            bus.shutdown()
        restore()
    if drive.failure is not None:
        raise EcamError(f"interface {args.interface!r} channel {channel!r} failed while the drive "
                        f"ran: {drive.failure}")
    if deaf:
        raise EcamError(f"the drive's serving thread on interface {args.interface!r} channel "
                        f"{channel!r} stopped: the drive answered nothing more (see the log)")
    dropped = drive.runner.dropped + getattr(bus, "dropped", 0)
    if dropped:  # counted where they entered (the drive's runner, the echo-free UDP bus)
        print(f"dropped {dropped} received frames that were no CAN frames", flush=True)
    print("virtual drive stopped", flush=True)
    return 0


#: How often the main thread looks at the stop request and the serving thread [s].
_POLL_S = 0.05


def _stop_on_signals():
    """Let SIGTERM (a service manager, `kill`) and SIGINT (Ctrl-C) ask the drive to stop, so it
    stops between two frames, shuts its bus down and exits 0. A SIGINT the process was started
    with ignored (a background job of a shell) stays ignored.

    The handler only appends to a list: Python runs it in the main thread between two bytecodes,
    possibly inside ``Event.wait()`` holding the event's lock, so a handler that took that lock
    (``Event.set()``) deadlocked the drive on SIGTERM (issue 28, item 11). Returns the list (empty
    until a signal came) and the function that puts the previous handlers back."""
    signalled: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        return signalled, lambda: None  # signal handlers can be set from the main thread only
    previous = {}
    for signum in (signal.SIGTERM, signal.SIGINT):
        handler = signal.getsignal(signum)
        if signum == signal.SIGINT and handler is not signal.default_int_handler:
            continue  # ignored, or a handler of the caller's: leave it
        previous[signum] = signal.signal(signum, lambda number, frame: signalled.append(number))

    def restore() -> None:
        for signum, handler in previous.items():
            signal.signal(signum, handler)

    return signalled, restore
