"""`ecam drive` (and `hil-sim drive`): the virtual CiA 402 drive as a process of its own, for a
master under test in another process; one drive per node id given (``--node-id 5,6`` or
``--node-id 5 --node-id 6``), each on a bus of its own on the same channel, so one external
master runs a whole machine.

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
from ecam.errors import EcamError, InputError

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


def node_ids(value) -> list:
    """The node ids ``--node-id`` gave: None, an int, or a list of ints and lists (the option
    repeated, each a comma-separated list), flattened in order."""
    if value is None:
        return []
    if isinstance(value, (list, tuple)):
        return [n for item in value for n in node_ids(item)]
    return [value]


def parse_node_ids(text: str) -> list:
    """``--node-id`` as typed: one id or a comma-separated list (``5`` or ``5,6``); numbers are
    checked where the ids are used (:func:`drive_command`), so the message names the field."""
    out = []
    for part in text.split(","):
        try:
            out.append(int(part.strip(), 0))
        except ValueError:
            raise argparse.ArgumentTypeError(f"node id {part.strip()!r} should be an integer "
                                             "1..127 (or a comma-separated list of them)") from None
    return out


def check_node_ids(ids: list) -> list:
    """Each node id 1..127 (CiA 301) and distinct: one virtual drive per node on one bus."""
    seen = set()
    for node in ids:
        validate.integer("node_id", node, minimum=1, maximum=127)
        if node in seen:
            raise InputError(f"node_id: {node} should be distinct (given twice: one drive per "
                            "node on one bus)")
        seen.add(node)
    return ids


def drive_command(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Run one virtual drive per node id until Ctrl-C, SIGINT or SIGTERM (or until ``stop`` is
    set): one process can serve a whole machine to an external master.

    Parameters
    ----------
    args : argparse.Namespace
        ``interface``, ``channel``, ``node_id`` (an int, or a list: :func:`node_ids`),
        ``heartbeat_ms``, ``scene`` (see :func:`ecam.app.cli.add_drive_arguments`).
    stop : threading.Event, optional
        Set by the caller to stop the drives (tests run it in a thread).

    Returns
    -------
    int
        0 once stopped.

    Raises
    ------
    EcamError
        A bad or repeated node id (before any bus opens), a transport that cannot be opened,
        or a bus that failed while the drives ran.
    """
    import can

    from hil_sim.drive import VirtualDrive
    from hil_sim.rig import scene_drive_options

    # before any bus opens: a wrong id is bad input, not a bus error
    ids = check_node_ids(node_ids(args.node_id))
    options = {}
    if args.scene is not None:
        options, scene_node = scene_drive_options(args.scene)
        ids = ids or [scene_node]
    ids = ids or [1]
    drives, buses = [], []  # each drive on a bus of its own: it hears the others' frames
    channel = None
    try:
        for node in ids:
            bus, channel = open_drive_bus(args.interface, args.channel)
            if bus is not None:
                buses.append(bus)
            drives.append(VirtualDrive(channel=channel, node_id=node, bus=bus,
                                       heartbeat_ms=args.heartbeat_ms, **options))
    except BaseException:
        for drive in drives:
            drive.close()
        for bus in buses:
            bus.shutdown()
        raise
    stop = stop or threading.Event()
    signalled, restore = _stop_on_signals()
    what = (f"drive, node {ids[0]}" if len(ids) == 1
            else f"drives, nodes {', '.join(str(n) for n in ids)}")
    print(f"virtual CiA 402 {what}, on {args.interface} channel "
          f"{channel!r} ({_REACH[args.interface]}); Ctrl-C or SIGTERM stops it", flush=True)
    deaf = None
    try:
        for drive in drives:
            drive.start()
        # Polled, not waited on: the signal handler takes no lock (see _stop_on_signals), and
        # Event.is_set() takes none either.
        while not (stop.is_set() or signalled):
            if any(drive.failure is not None for drive in drives):
                break
            deaf = next((drive for drive in drives if not drive.runner.alive), None)
            if deaf is not None:
                break
            time.sleep(_POLL_S)
    except KeyboardInterrupt:
        pass  # SIGINT before its handler was set, or where none could be set
    except (can.CanError, OSError) as exc:  # a boot-up could not be sent
        raise EcamError(f"interface {args.interface!r} channel {channel!r} failed: {exc}") from None
    finally:
        for drive in drives:
            drive.stop()
        for bus in buses:
            bus.shutdown()
        restore()
    failed = next((drive for drive in drives if drive.failure is not None), None)
    node = f" (node {failed.node_id})" if failed is not None and len(drives) > 1 else ""
    if failed is not None:
        raise EcamError(f"interface {args.interface!r} channel {channel!r} failed while the drive"
                        f"{node} ran: {failed.failure}")
    if deaf is not None:
        node = f" (node {deaf.node_id})" if len(drives) > 1 else ""
        raise EcamError(f"the drive's serving thread{node} on interface {args.interface!r} channel "
                        f"{channel!r} stopped: the drive answered nothing more (see the log)")
    dropped = (sum(drive.runner.dropped for drive in drives)
               + sum(getattr(bus, "dropped", 0) for bus in buses))
    if dropped:  # counted where they entered (the drive's runner, the echo-free UDP bus)
        print(f"dropped {dropped} received frames that were no CAN frames", flush=True)
    print("virtual drive stopped" if len(drives) == 1 else "virtual drives stopped", flush=True)
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
