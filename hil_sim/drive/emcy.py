"""EMCY: the drive's emergency producer, with the error codes and error register bits it uses."""

from __future__ import annotations

import struct

from hil_sim.drive.cia402 import OPERATIONAL, PRE_OPERATIONAL
from hil_sim.drive.objects import CAN_ID_MASK, COB_ID_EMCY

#: EMCY error codes (CiA 301 / 402) and error register bits (0x1001).
EMCY_NO_ERROR = 0x0000  # error reset
EMCY_FOLLOWING_ERROR = 0x8611
EMCY_PDO_LENGTH = 0x8210
# CiA 301, emergency error codes: 6100 internal software. An exception escaped one of the drive's
# handlers (a defect of the drive): the drive faults rather than run on in an unknown state.
EMCY_INTERNAL_SOFTWARE = 0x6100
# CiA 301, emergency error codes: 81xx communication. The SYNC stopped arriving.
EMCY_COMMUNICATION = 0x8100
# CiA 301, emergency error codes: 8240 unexpected SYNC data length (the code CANopenNode reports a
# SYNC of the wrong length for 0x1019 with, 301/CO_Emergency.h CO_EMC_SYNC_DATA_LENGTH).
EMCY_SYNC_DATA_LENGTH = 0x8240
ERROR_REGISTER_GENERIC = 0x01
ERROR_REGISTER_COMMUNICATION = 0x10
ERROR_REGISTER_PROFILE = 0x20


class EmcyProducer:
    """Sends EMCY frames on the COB-ID of 0x1014.

    Parameters
    ----------
    network : canopen.Network
        Where the frames go.
    objects : hil_sim.drive.sdo.StoredObjects
        The stored objects; 0x1014 is read at every EMCY, so the frame goes where the object
        dictionary says at that moment.
    nmt : hil_sim.drive.nmt.NmtSlave
        The NMT state, which decides whether an EMCY may be sent.
    """

    def __init__(self, network, objects, nmt) -> None:
        self.network = network
        self.objects = objects
        self.nmt = nmt

    def send(self, code: int, register: int) -> None:
        """Send an EMCY (not while STOPPED, CiA 301)."""
        if self.nmt.state in (PRE_OPERATIONAL, OPERATIONAL):
            cob = self.objects.stored(COB_ID_EMCY) & CAN_ID_MASK
            self.network.send_message(cob, struct.pack("<HB5s", code, register, b""))
