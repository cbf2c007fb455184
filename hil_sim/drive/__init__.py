"""A virtual CiA 402 servo drive: a CANopen slave on a python-can bus, driving a simulated axis.

The drive is a canopen :class:`~canopen.LocalNode` (object dictionary from ``drive.eds``, SDO
server with segmented transfer) plus what canopen 2.4 leaves to the application, one module per
protocol service:

* :mod:`~hil_sim.drive.objects`: the EDS, its loader, and a name for every object the drive uses;
* :mod:`~hil_sim.drive.sdo`: the SDO server (expedited and segmented, CiA 301: every frame a
  client may send, short, stray or garbled, gets the CiA 301 abort naming the right object,
  a stalled transfer times out, the indicated size of a segmented download is enforced), the
  node, the stored objects, the abort codes; every written number is checked against the
  limits the EDS documents;
* :mod:`~hil_sim.drive.nmt`: the **NMT** slave written here (boot-up, pre-operational,
  operational, stopped, resets) with a heartbeat produced on the drive's own clock (canopen's
  uses a timer thread);
* :mod:`~hil_sim.drive.pdo`: **PDOs** packed and unpacked here from the mapping objects
  (0x1400-0x1BFF), and received RPDO values written into the drive's object dictionary (canopen
  does not);
* :mod:`~hil_sim.drive.emcy`: the EMCY producer and its error codes;
* :mod:`~hil_sim.drive.power_state`: the **CiA 402 power state machine** run from the tables of
  :mod:`hil_sim.drive.cia402` (:data:`COMMANDS`, :data:`TRANSITIONS`,
  :data:`STATUSWORD_OF_STATE`), modes of operation 0x6060/0x6061 with cyclic synchronous
  position (8), following-error monitoring (window 0x6065, time out 0x6066) raising a fault with
  EMCY 0x8611;
* :mod:`~hil_sim.drive.cam_slot`: the **drive-side cam**: a table blob downloaded into 0x2000 is
  verified with :meth:`ecam.CamTable.from_bytes` into a pending slot and activated atomically by
  writing 1 to 0x2001:01; a bad, truncated or aborted download is refused and the running table
  keeps running. With cam mode 0x2004 = 1 the target is the cam at the master position 0x2003;
  0x2001:01 = 3 queues the pending table for where the master leaves the running table's
  period (either way, as the firmware's ``ecam_table_pair``), 4 for where it crosses 0x2001:06,
  placed as 0x2001:05 says (master and slave absolute or relative, PLCopen MC_CamTableSelect)
  with MC_CamIn's offsets and scaling from 0x2001:07..0C (:mod:`~hil_sim.drive.cam_coupling`);
  5 leaves the cam and stops within 0x6083/0x6084/0x60A4:01 (:mod:`~hil_sim.drive.cam_out`);
* :mod:`~hil_sim.drive.runner`: when frames are handled, and the bus; the one door every
  received frame passes: 29-bit, remote and error frames stay out, and an exception that
  escapes a handler (a defect) is logged and faults the drive with EMCY 0x6100 instead of
  leaving it;
* :mod:`~hil_sim.drive.virtual_drive`: :class:`VirtualDrive`, which composes them and runs the
  **SYNC** cycle: each SYNC latches the synchronous RPDOs, advances the drive by one
  interpolation period (0x60C2), runs :meth:`ServoAxis.cycle`, then sends the synchronous TPDOs.

canopen 2.4 internals this relies on (canopen is pinned below 2.5): ``LocalNode._write_callbacks``
and ``LocalNode._find_object``.

Two ways to run it:

* lock-step (the rig): :meth:`VirtualDrive.boot`, then :meth:`VirtualDrive.process` whenever
  frames may be waiting; every frame is handled at a defined point and all timestamps are
  simulated;
* free-running (an external master, e.g. canopen's ``BaseNode402``): :meth:`VirtualDrive.start`
  / :meth:`VirtualDrive.stop` run a thread that handles frames as they come; heartbeats follow
  the wall clock, the control loop still advances one interpolation period per SYNC.
"""

import importlib

# Each public name and the module it lives in, imported on first use (PEP 562): the scene reader
# takes the 0x60C2 encoding from hil_sim.drive.objects, and importing that runs this package,
# which must therefore not load canopen and python-can by itself.
_HOMES = {
    "hil_sim.drive.cam_slot": (
        "CAM_COMMAND_ACTIVATE", "CAM_COMMAND_DISCARD", "CAM_STATUS_ACTIVE",
        "CAM_STATUS_LAST_DOWNLOAD_REFUSED", "CAM_STATUS_PENDING",
    ),
    "hil_sim.drive.emcy": (
        "EMCY_COMMUNICATION", "EMCY_FOLLOWING_ERROR", "EMCY_INTERNAL_SOFTWARE", "EMCY_PDO_LENGTH",
        "ERROR_REGISTER_COMMUNICATION", "ERROR_REGISTER_GENERIC", "ERROR_REGISTER_PROFILE",
    ),
    "hil_sim.drive.objects": ("EDS_PATH", "PROCESS_OBJECTS", "interpolation_period_s", "load_od"),
    "hil_sim.drive.sdo": (
        "ABORT_CANNOT_MAP", "ABORT_CANNOT_STORE", "ABORT_COMMAND_SPECIFIER", "ABORT_DEVICE_STATE",
        "ABORT_INVALID_VALUE", "ABORT_PDO_LENGTH", "ABORT_TIMEOUT", "ABORT_TOGGLE",
        "ABORT_VALUE_TOO_HIGH", "ABORT_VALUE_TOO_LOW", "SDO_TIMEOUT_S",
    ),
    "hil_sim.drive.virtual_drive": ("VirtualDrive",),
    "hil_sim.int32": ("saturate_int32", "wrap_int32"),  # their home before hil_sim.int32
}
_LAZY = {name: module for module, names in _HOMES.items() for name in names}
__all__ = sorted(_LAZY)


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'hil_sim.drive' has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *__all__})
