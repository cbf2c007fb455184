"""The drive's object dictionary: the EDS file, its loader, and a name for every entry the drive
uses, spelled as the EDS's ``ParameterName``.

Each entry is an :class:`ObjectKey` (index, subindex); it is a tuple, so it is the same dict
key as the ``(obj.index, obj.subindex)`` pairs built from PDO mappings.

This module loads no CAN stack until an object dictionary is loaded (:func:`load_od`): the scene
reader takes the 0x60C2 encoding from here without pulling in canopen.
"""

from __future__ import annotations

import copy
import functools
import math
from pathlib import Path
from typing import NamedTuple

from hil_sim.int32 import saturate_int32, wrap_int32  # noqa: F401 - re-exported (their home before hil_sim.int32)

#: The drive's electronic data sheet, shipped beside this module.
EDS_PATH = Path(__file__).with_name("drive.eds")


class ObjectKey(NamedTuple):
    """One entry of the object dictionary."""

    index: int
    subindex: int = 0


# CiA 301 object dictionary areas: what NMT reset communication and reset application restore
# to their power-on values.
COMMUNICATION_AREA = range(0x1000, 0x2000)
APPLICATION_AREA = range(0x2000, 0x10000)  # manufacturer and standardised profile areas

# CiA 301 communication objects.
ERROR_REGISTER = ObjectKey(0x1001)
COB_ID_SYNC = ObjectKey(0x1005)
COMMUNICATION_CYCLE_PERIOD = ObjectKey(0x1006)  # us; 0: SYNC not supervised
COB_ID_EMCY = ObjectKey(0x1014)
PRODUCER_HEARTBEAT_TIME = ObjectKey(0x1017)  # ms
#: CiA 301 7.5.2.22: 0, the SYNC has no data; 2..240, it carries a counter that runs 1..this value.
SYNC_COUNTER_OVERFLOW = ObjectKey(0x1019)

# CiA 301 PDO parameters: four RPDOs and four TPDOs, numbered from these indexes.
RPDO_COMMUNICATION_PARAMETER = 0x1400
RPDO_MAPPING_PARAMETER = 0x1600
TPDO_COMMUNICATION_PARAMETER = 0x1800
TPDO_MAPPING_PARAMETER = 0x1A00
PDO_PARAMETERS = range(0x1400, 0x1C00)  # all communication and mapping parameters
MAPPING_PARAMETERS = (range(0x1600, 0x1800), range(0x1A00, 0x1C00))  # RPDO, TPDO
COMMUNICATION_PARAMETERS = (range(0x1400, 0x1600), range(0x1800, 0x1A00))  # RPDO, TPDO
COB_ID_USED_BY_PDO = 1  # subindex of a communication parameter
TRANSMISSION_TYPE = 2  # subindex of a communication parameter
SYNC_START_VALUE = 6  # subindex of a TPDO communication parameter (CiA 301 7.5.2.37)
NUMBER_OF_MAPPED_OBJECTS = 0  # subindex of a mapping parameter

# CiA 301 data types (the EDS's DataType) -> struct code, for the types PDOs carry: BOOLEAN,
# INTEGER8/16/32, UNSIGNED8/16/32, REAL32, INTEGER64, UNSIGNED64 (little-endian on the bus).
STRUCT_CODES = {
    0x01: "?", 0x02: "b", 0x03: "h", 0x04: "i", 0x05: "B", 0x06: "H", 0x07: "I",
    0x08: "f", 0x15: "q", 0x1B: "Q",
}

# CiA 301: a COB-ID object holds the 11-bit CAN id in its low bits; bit 31 of a PDO's marks
# the PDO as not existing.
CAN_ID_MASK = 0x7FF
PDO_NOT_VALID = 0x80000000

# CiA 301 pre-defined connection set: COB-IDs as function code + node id.
NMT_COB_ID = 0x000
SDO_RECEIVE_COB_ID = 0x600  # client -> server
SDO_TRANSMIT_COB_ID = 0x580  # server -> client
HEARTBEAT_COB_ID = 0x700

# CiA 402 drive objects.
ABORT_CONNECTION_OPTION_CODE = ObjectKey(0x6007)  # reaction to a lost connection
ERROR_CODE = ObjectKey(0x603F)
CONTROLWORD = ObjectKey(0x6040)
STATUSWORD = ObjectKey(0x6041)
MODES_OF_OPERATION = ObjectKey(0x6060)
MODES_OF_OPERATION_DISPLAY = ObjectKey(0x6061)
POSITION_ACTUAL_VALUE = ObjectKey(0x6064)  # counts
FOLLOWING_ERROR_WINDOW = ObjectKey(0x6065)  # counts
FOLLOWING_ERROR_TIME_OUT = ObjectKey(0x6066)  # ms
VELOCITY_ACTUAL_VALUE = ObjectKey(0x606C)  # counts/s
MOTOR_RATED_TORQUE = ObjectKey(0x6076)  # mN m
TORQUE_ACTUAL_VALUE = ObjectKey(0x6077)  # per mille of the rated torque
TARGET_POSITION = ObjectKey(0x607A)  # counts
VELOCITY_OFFSET = ObjectKey(0x60B1)  # counts/s
# The profile limits a drive-side cam-out stops within (CiA 402-2: profile acceleration,
# profile deceleration, profile jerk 1): counts/s^2, counts/s^2, counts/s^3.
PROFILE_ACCELERATION = ObjectKey(0x6083)
PROFILE_DECELERATION = ObjectKey(0x6084)
PROFILE_JERK = ObjectKey(0x60A4, 1)
INTERPOLATION_TIME_PERIOD = 0x60C2
INTERPOLATION_TIME_PERIOD_VALUE = ObjectKey(0x60C2, 1)
INTERPOLATION_TIME_INDEX = ObjectKey(0x60C2, 2)
FOLLOWING_ERROR_ACTUAL_VALUE = ObjectKey(0x60F4)  # counts

# Manufacturer objects: the drive-side cam (blob format: firmware_tables/FORMAT.md).
CAM_TABLE_DOWNLOAD = ObjectKey(0x2000)
CAM_COMMAND = ObjectKey(0x2001, 1)
CAM_STATUS = ObjectKey(0x2001, 2)
CAM_LAST_ERROR_CODE = ObjectKey(0x2001, 3)
CAM_LAST_ERROR_MESSAGE = ObjectKey(0x2001, 4)
CAM_SWITCH_MODE = ObjectKey(0x2001, 5)  # bit 0 master relative, bit 1 slave relative
CAM_ACTIVATION_POSITION = ObjectKey(0x2001, 6)  # master counts (INTEGER64): command 4's
# MC_CamIn's offsets and scaling of the next activation (hil_sim.drive.cam_coupling)
CAM_MASTER_OFFSET = ObjectKey(0x2001, 7)  # table master counts (INTEGER64)
CAM_SLAVE_OFFSET = ObjectKey(0x2001, 8)  # slave counts (INTEGER32)
CAM_MASTER_SCALING_NUMERATOR = ObjectKey(0x2001, 9)
CAM_MASTER_SCALING_DENOMINATOR = ObjectKey(0x2001, 10)
CAM_SLAVE_SCALING_NUMERATOR = ObjectKey(0x2001, 11)
CAM_SLAVE_SCALING_DENOMINATOR = ObjectKey(0x2001, 12)
ACTIVE_CAM_TABLE_CRC32 = ObjectKey(0x2002)
MASTER_POSITION = ObjectKey(0x2003)  # master counts
CAM_MODE = ObjectKey(0x2004)
PENDING_CAM_TABLE_CRC32 = ObjectKey(0x2005)

#: Objects the drive keeps live (served by callbacks, written by RPDOs). Everything else lives
#: in canopen's data store with the EDS defaults.
PROCESS_OBJECTS = (
    ERROR_REGISTER, ERROR_CODE, CONTROLWORD, STATUSWORD, MODES_OF_OPERATION,
    MODES_OF_OPERATION_DISPLAY, POSITION_ACTUAL_VALUE, FOLLOWING_ERROR_WINDOW,
    FOLLOWING_ERROR_TIME_OUT, VELOCITY_ACTUAL_VALUE, MOTOR_RATED_TORQUE, TORQUE_ACTUAL_VALUE,
    TARGET_POSITION, VELOCITY_OFFSET, FOLLOWING_ERROR_ACTUAL_VALUE, CAM_COMMAND, CAM_STATUS,
    CAM_LAST_ERROR_CODE, CAM_LAST_ERROR_MESSAGE, ACTIVE_CAM_TABLE_CRC32, MASTER_POSITION,
    CAM_MODE, PENDING_CAM_TABLE_CRC32, CAM_SWITCH_MODE, CAM_ACTIVATION_POSITION, CAM_MASTER_OFFSET,
    CAM_SLAVE_OFFSET, CAM_MASTER_SCALING_NUMERATOR, CAM_MASTER_SCALING_DENOMINATOR,
    CAM_SLAVE_SCALING_NUMERATOR, CAM_SLAVE_SCALING_DENOMINATOR, PROFILE_ACCELERATION,
    PROFILE_DECELERATION, PROFILE_JERK,
)


@functools.lru_cache(maxsize=8)
def _parsed_od(path: str, node_id: int):
    import canopen  # here, not at the top: see the module docstring

    return canopen.import_od(path, node_id)


def load_od(path, node_id: int):
    """The object dictionary of an EDS file for ``node_id``: parsed once, then a deep copy per
    caller, so runs share the parsing cost but never any state."""
    return copy.deepcopy(_parsed_od(str(path), node_id))


# 0x60C2 interpolation time period (CiA 402): value (UNSIGNED8, subindex 1) x 10^index s
# (INTEGER8, subindex 2). The rig writes index -6..0 (1 us .. 1 s resolution: the periods the
# drive runs are 10 us .. 1 s; the EDS allows index -7..0).
INTERPOLATION_TIME_INDEXES = range(-6, 1)


def interpolation_period(cycle_s: float) -> tuple[int, int] | None:
    """The bus cycle as CiA 402 object 0x60C2 (interpolation time period) holds it; the inverse
    of :func:`interpolation_period_s`.

    Parameters
    ----------
    cycle_s : float
        The cycle [s].

    Returns
    -------
    tuple of (int, int) or None
        ``(value, index)`` with ``value x 10^index == cycle_s``, value in 1..255 (UNSIGNED8)
        and index in -6..0, the finest index that fits first; None when the cycle has no such
        form (e.g. 1/3 ms).
    """
    for index in INTERPOLATION_TIME_INDEXES:
        value = cycle_s / 10.0**index
        if 1 <= round(value) <= 255 and math.isclose(value, round(value), rel_tol=1e-9):
            return round(value), index
    return None


def interpolation_period_s(value: int, index: int) -> float:
    """0x60C2 (CiA 402: interpolation time period = value x 10^index s) in seconds; the inverse
    of :func:`interpolation_period`.

    Divides for negative indexes: 10 x 10.0**-6 is 9.999...e-6, below the 10 us the scene
    validator allows, where 10 / 10**6 is exactly the float nearest 1e-5.
    """
    return value / 10.0 ** -index if index < 0 else value * 10.0 ** index

