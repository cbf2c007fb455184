"""Queued table switching at a period boundary: the Python twin of firmware_tables/ecam_table_pair.c.

A :class:`SwitchPair` holds a running :class:`~ecam.table.CamTable` and, once armed, a pending
one that takes over exactly where the master crosses the running table's period boundary: in the
sample that crosses it, at the boundary count itself going forwards and at the count below it
going backwards (each table keeps the half-open period it owns), never a count early or late. A
jump over several periods switches at the first boundary crossed. A running table that does not
repeat has one period, its master range; leaving it ends the profile, and a pending table takes
over at the end crossed, or, armed after the profile ended, at the next sample's master position.

Coordinates follow PLCopen per axis (PLCopen TC2, Function Blocks for Motion Control, Version 2.0
(formerly Part 1 and Part 2), 2011: ``MC_CamTableSelect.MasterAbsolute`` / ``SlaveAbsolute``;
``MC_CamIn`` ``MasterOffset``, ``SlaveOffset``, ``StartMode``), as CODESYS SM3_Basic spells out a
switch ("Function Blocks: MC_CamTableSelect and MC_CamIn") and as :func:`ecam.cam_join.join_cams`
(``ecam check A --then B``) predicts it:

* offsets: ``MasterOffset`` and ``SlaveOffset`` come with the engagement and again with each
  switch (a new ``MC_CamIn``): the table is looked up at ``X = master - zero + MasterOffset``
  ("X = MasterScaling * MasterPosition + MasterOffset", scaling 1) and the slave is
  ``CAM(X) + SlaveOffset + base``; the engagement is StartMode absolute (zero = base = 0);
* master ``"absolute"``: zero = 0 (the table "is started at the current master position");
  refused for a table that does not repeat, whose range the boundary can miss (CODESYS:
  SMC_CI_MASTER_OUT_OF_SCALE);
* master ``"relative"``: zero = the boundary ("sets the zero point of the master to ... the
  position at the end of the previous cam"); a table that does not repeat must contain
  ``MasterOffset``, where it is entered;
* slave ``"absolute"``: base = 0 ("evaluated independent of the current position of the slave.
  This can lead to jumps");
* slave ``"relative"``: base = the slave's position at the boundary ("The position that the slave
  has after the end of the previous cycle is added as a slave offset"), so with ``SlaveOffset``
  0 the switch is continuous in position when the pending table is 0 where it is entered.

The arithmetic is the C runtime's, bit for bit: master positions are int64 counts modulo 2^64,
slave positions int32 counts modulo 2^32, and every refusal has the C code
(:data:`STATUS`; :class:`SwitchRefused` carries it).
"""

from __future__ import annotations

from typing import NamedTuple

import ecam.validate as validate  # the module, not the package: no edge to ecam/__init__
from .errors import InputError
from .table import CamTable

__all__ = ["CODES", "COORDINATES", "MASTER_RELATIVE", "SLAVE_RELATIVE", "STATUS", "Sample", "SwitchPair",
           "SwitchRefused", "mode_flags"]

#: ``ECAM_SWITCH_MASTER_RELATIVE`` / ``ECAM_SWITCH_SLAVE_RELATIVE``: PLCopen MasterAbsolute /
#: SlaveAbsolute FALSE.
MASTER_RELATIVE = 1
SLAVE_RELATIVE = 2
#: How a table's coordinates are placed on an axis when it is switched in (PLCopen).
COORDINATES = ("absolute", "relative")
#: The C results (ecam_table_pair.h) by code.
STATUS = {
    0: "ECAM_SWITCH_OK", 1: "ECAM_SWITCH_DONE", -40: "ECAM_SWITCH_E_NULL", -41: "ECAM_SWITCH_E_NOT_ENGAGED",
    -42: "ECAM_SWITCH_E_TABLE", -43: "ECAM_SWITCH_E_MODE", -44: "ECAM_SWITCH_E_ARMED",
    -45: "ECAM_SWITCH_E_NO_PENDING", -46: "ECAM_SWITCH_E_MASTER_RANGE", -47: "ECAM_SWITCH_E_SWITCHED",
}  # fmt: skip
#: The C codes by name.
CODES = {name: code for code, name in STATUS.items()}

_U64 = (1 << 64) - 1
_U32 = (1 << 32) - 1


def _s64(u: int) -> int:
    u &= _U64
    return u - (1 << 64) if u >> 63 else u


def _s32(u: int) -> int:
    u &= _U32
    return u - (1 << 32) if u >> 31 else u


def mode_flags(master: str = "absolute", slave: str = "absolute") -> int:
    """The C mode of a switch from PLCopen's words.

    Parameters
    ----------
    master, slave : {"absolute", "relative"}
        ``MC_CamTableSelect.MasterAbsolute`` / ``SlaveAbsolute`` (absolute: TRUE).

    Returns
    -------
    int
        ``MASTER_RELATIVE | SLAVE_RELATIVE`` bits, as ``ecam_switch_arm`` takes them.
    """
    validate.choice("master", master, COORDINATES)
    validate.choice("slave", slave, COORDINATES)
    return (MASTER_RELATIVE if master == "relative" else 0) | (SLAVE_RELATIVE if slave == "relative" else 0)


class SwitchRefused(InputError):
    """A refused call; ``status`` is the C result's name, ``code`` its value (:data:`STATUS`)."""

    def __init__(self, message: str, status: str):
        super().__init__(f"{message} ({status})")
        self.status = status
        self.code = CODES[status]


class Sample(NamedTuple):
    """One step's outputs: what ``ecam_switch_step`` returns.

    Attributes
    ----------
    position : int
        Slave position [counts], int32 (modulo 2^32, as the C runtime's).
    slope : int
        The running table's slope, Q16 slave counts per master count.
    switched : bool
        The pending table took over at this sample (C: ``ECAM_SWITCH_DONE``); the outputs are
        already the new table's.
    """

    position: int
    slope: int
    switched: bool


class SwitchPair:
    """A running and a pending cam table, switched at a period boundary (module docstring).

    Not engaged when made: :meth:`engage` it with the first table, then call :meth:`step` with
    each master position; :meth:`arm` queues the next table, :meth:`cancel` withdraws it.
    """

    def __init__(self):
        self._clear()

    def _clear(self) -> None:
        self._running = None
        self._pending = None
        self._armed = False
        self._mode = 0
        self._switches = 0
        self._pending_master = 0  # the pending switch's MasterOffset (mod 2^64)
        self._pending_slave = 0  # and SlaveOffset (mod 2^32)
        self._origin = 0  # master position (mod 2^64) where the running table's lookup sees 0
        self._window = 0  # the running table's master at the start of the last sample's period
        self._boundary = 0
        self._offset = 0  # added to the running table's position (mod 2^32)
        self._started = False
        self._ended = False

    # --------------------------------------------------------------------------- state
    @property
    def running(self) -> CamTable | None:
        """The table looked up (None until engaged)."""
        return self._running

    @property
    def pending(self) -> CamTable | None:
        """The armed table, None when nothing is armed."""
        return self._pending if self._armed else None

    @property
    def switches(self) -> int:
        """Switches done since the engagement (modulo 2^32, as ``ecam_switch_count``)."""
        return self._switches

    @property
    def boundary(self) -> int:
        """Master position [counts] of the last switch's boundary; 0 before any."""
        return _s64(self._boundary)

    @property
    def offset(self) -> int:
        """What is added to the running table's position [counts, int32]."""
        return _s32(self._offset)

    # --------------------------------------------------------------------------- commands
    def engage(self, table: CamTable, master_offset: int = 0, slave_offset: int = 0) -> None:
        """Engage ``table`` (``MC_CamIn``, StartMode absolute); clears any armed switch.

        Parameters
        ----------
        table : CamTable
            Looked up at ``master + master_offset``.
        master_offset : int
            PLCopen MasterOffset [master counts, int64].
        slave_offset : int
            PLCopen SlaveOffset [slave counts, int32], added to the table's position.

        Raises
        ------
        SwitchRefused
            ``ECAM_SWITCH_E_NULL`` (None), ``ECAM_SWITCH_E_TABLE`` (not a CamTable).
        InputError
            An offset outside int64 / int32.
        """
        validate.integer("master_offset", master_offset, minimum=-(1 << 63), maximum=(1 << 63) - 1)
        validate.integer("slave_offset", slave_offset, minimum=-(1 << 31), maximum=(1 << 31) - 1)
        _check_table(table)
        self._clear()
        self._origin = -master_offset & _U64
        self._offset = slave_offset & _U32
        self._running = table

    def arm(self, table: CamTable, master: str = "absolute", slave: str = "absolute", master_offset: int = 0,
            slave_offset: int = 0) -> None:
        """Queue ``table`` to take over at the next period boundary the master crosses.

        Parameters
        ----------
        table : CamTable
        master, slave : {"absolute", "relative"}
            PLCopen ``MC_CamTableSelect.MasterAbsolute`` / ``SlaveAbsolute`` (absolute: TRUE).
        master_offset : int
            The switch's ``MC_CamIn.MasterOffset`` [master counts, int64].
        slave_offset : int
            The switch's ``MC_CamIn.SlaveOffset`` [slave counts, int32].

        Raises
        ------
        SwitchRefused
            As :meth:`arm_mode`.
        """
        self.arm_mode(table, mode_flags(master, slave), master_offset, slave_offset)

    def arm_mode(self, table: CamTable, mode: int, master_offset: int = 0, slave_offset: int = 0) -> None:
        """:meth:`arm` with the C mode bits (``ecam_switch_arm``).

        Raises
        ------
        SwitchRefused
            In the C order: ``E_NULL`` (None), ``E_NOT_ENGAGED``, ``E_ARMED`` (a switch is
            already armed), ``E_TABLE`` (not a CamTable), ``E_MODE`` (a bit other than
            :data:`MASTER_RELATIVE` and :data:`SLAVE_RELATIVE`), ``E_MASTER_RANGE`` (a table that
            does not repeat with the master absolute, or entered at a ``master_offset`` outside
            its range). A refusal changes nothing.
        InputError
            An offset outside int64 / int32.
        """
        validate.integer("master_offset", master_offset, minimum=-(1 << 63), maximum=(1 << 63) - 1)
        validate.integer("slave_offset", slave_offset, minimum=-(1 << 31), maximum=(1 << 31) - 1)
        if table is None:
            raise SwitchRefused("table: None should be a CamTable", "ECAM_SWITCH_E_NULL")
        if self._running is None:
            raise SwitchRefused("running: None should be a table: engage the pair first", "ECAM_SWITCH_E_NOT_ENGAGED")
        if self._armed:
            raise SwitchRefused("pending: armed should be empty: cancel the armed switch first", "ECAM_SWITCH_E_ARMED")
        _check_table(table)
        if isinstance(mode, bool) or not isinstance(mode, int) or mode & ~(MASTER_RELATIVE | SLAVE_RELATIVE):
            raise SwitchRefused(f"mode: {validate.show(mode)} should be 0..3 (MASTER_RELATIVE | SLAVE_RELATIVE)",
                                "ECAM_SWITCH_E_MODE")
        if not table.periodic and not mode & MASTER_RELATIVE:
            raise SwitchRefused(f"master: 'absolute' should be 'relative' for a table that does not repeat: the "
                                f"boundary can fall outside its master range 0..{table.master_counts}",
                                "ECAM_SWITCH_E_MASTER_RANGE")
        if not table.periodic and not 0 <= master_offset <= table.master_counts:
            raise SwitchRefused(f"master_offset: {master_offset} should be within the master range "
                                f"0..{table.master_counts} of a table that does not repeat, where it is entered",
                                "ECAM_SWITCH_E_MASTER_RANGE")
        self._pending = table
        self._mode = mode
        self._pending_master = master_offset & _U64
        self._pending_slave = slave_offset & _U32
        self._armed = True

    def cancel(self) -> None:
        """Withdraw the armed switch.

        Raises
        ------
        SwitchRefused
            ``ECAM_SWITCH_E_NO_PENDING`` when nothing is armed. (The C function may also answer
            ``ECAM_SWITCH_E_SWITCHED``, when the interrupt switched while it ran.)
        """
        if not self._armed:
            raise SwitchRefused("pending: none should be an armed switch to cancel", "ECAM_SWITCH_E_NO_PENDING")
        self._armed = False

    def step(self, master: int) -> Sample:
        """One sample at ``master`` [counts, int64] (``ecam_switch_step``).

        Returns
        -------
        Sample
            The slave position and slope, and whether the pending table took over here.

        Raises
        ------
        SwitchRefused
            ``ECAM_SWITCH_E_NOT_ENGAGED`` (the C function then outputs ``ECAM_INVALID``).
        InputError
            ``master`` outside int64.
        """
        validate.integer("master", master, minimum=-(1 << 63), maximum=(1 << 63) - 1)
        if self._running is None:
            raise SwitchRefused("running: None should be a table: engage the pair first", "ECAM_SWITCH_E_NOT_ENGAGED")
        local = (master - self._origin) & _U64
        switched = False
        if self._ended or not self._started or (local - self._window) & _U64 >= self._running.master_counts:
            local, switched = self._cross(master, local)
        position, slope = self._running.lookup(_s64(local), with_slope=True)
        return Sample(_s32(position + self._offset), int(slope), switched)

    # --------------------------------------------------------------------------- the C's cold path
    def _cross(self, master: int, local: int) -> tuple[int, bool]:
        table = self._running
        if not self._started:
            self._started = True
            self._window = _window(table, local)
            self._ended = _outside(table, local, self._window)
            return local, False
        if self._ended:
            if self._armed:
                return self._take_over(local, master), True
            self._ended = _outside(table, local, self._window)
            return local, False
        forwards = _s64(local - self._window) >= 0
        boundary = (self._window + table.master_counts) & _U64 if forwards else self._window
        if self._armed:
            return self._take_over(boundary, master), True
        self._window = _window(table, local)
        self._ended = _outside(table, local, self._window)
        return local, False

    def _take_over(self, boundary: int, master: int) -> int:
        at = (self._running.lookup(_s64(boundary)) + self._offset) & _U32
        where = (boundary + self._origin) & _U64
        # X = master - zero + MasterOffset, Y = CAM(X) + SlaveOffset + base
        self._origin = ((where if self._mode & MASTER_RELATIVE else 0) - self._pending_master) & _U64
        self._offset = ((at if self._mode & SLAVE_RELATIVE else 0) + self._pending_slave) & _U32
        self._running = self._pending
        self._boundary = where
        local = (master - self._origin) & _U64
        self._window = _window(self._running, local)
        self._ended = _outside(self._running, local, self._window)
        self._armed = False
        self._pending = None
        self._switches = (self._switches + 1) & _U32
        return local


def _check_table(table) -> None:
    if table is None:
        raise SwitchRefused("table: None should be a CamTable", "ECAM_SWITCH_E_NULL")
    if not isinstance(table, CamTable):
        raise SwitchRefused(f"table: {validate.show(table)} should be a CamTable ready to look up",
                            "ECAM_SWITCH_E_TABLE")


def _window(table: CamTable, local: int) -> int:
    """The start of the period holding ``local`` (mod 2^64); 0 for a table that does not repeat."""
    if not table.periodic:
        return 0
    return (local - _s64(local) % table.master_counts) & _U64


def _outside(table: CamTable, local: int, window: int) -> bool:
    return not table.periodic and (local - window) & _U64 >= table.master_counts
