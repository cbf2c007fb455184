"""The CiA 402 power state machine as the drive applies it: controlword, statusword, modes of
operation (0x6060/0x6061) and following-error monitoring (window 0x6065, time out 0x6066)
raising a fault with EMCY 0x8611.

The tables it runs on (states, commands, transitions, statusword bits) are data in
:mod:`hil_sim.drive.cia402`.
"""

from __future__ import annotations

from canopen.sdo import SdoAbortedError

from hil_sim.drive.cia402 import (
    COMMANDS, CW_FAULT_RESET, CYCLIC_SYNCHRONOUS_POSITION, FAULT, FAULT_REACTION_ACTIVE,
    NOT_READY_TO_SWITCH_ON, OPERATION_ENABLED, QUICK_STOP_ACTIVE, STATUSWORD_OF_STATE,
    SUPPORTED_MODES, SW_FOLLOWING_COMMAND, SW_FOLLOWING_ERROR, SW_REMOTE, SWITCH_ON_DISABLED,
    TRANSITIONS,
)
from hil_sim.drive.emcy import (
    EMCY_FOLLOWING_ERROR, EMCY_NO_ERROR, ERROR_REGISTER_GENERIC, ERROR_REGISTER_PROFILE,
)
from hil_sim.drive.objects import (
    CONTROLWORD, ERROR_CODE, ERROR_REGISTER, FOLLOWING_ERROR_TIME_OUT, FOLLOWING_ERROR_WINDOW,
    MODES_OF_OPERATION, MODES_OF_OPERATION_DISPLAY, STATUSWORD, TARGET_POSITION, VELOCITY_OFFSET,
)
from hil_sim.drive.sdo import ABORT_INVALID_VALUE
from hil_sim.int32 import wrap_int32

#: 0x6065 value that switches the following-error check off.
FOLLOWING_ERROR_WINDOW_OFF = 0xFFFFFFFF


class PowerStateMachine:
    """The drive's CiA 402 state, driven by the controlword and by faults.

    Parameters
    ----------
    values : dict
        The drive's live objects.
    emcy : hil_sim.drive.emcy.EmcyProducer
        Reports faults and their reset.
    position_counts : callable
        The axis position now [counts], where CSP starts and where a stop holds.
    on_enable : callable
        Called on entering OPERATION ENABLED other than from QUICK STOP ACTIVE.
    """

    def __init__(self, values: dict, emcy, position_counts, on_enable) -> None:
        self.values = values
        self.emcy = emcy
        self._position_counts = position_counts
        self._on_enable = on_enable
        self.state = NOT_READY_TO_SWITCH_ON
        self.last_controlword = 0  # for the rising edge of fault reset
        self.hold_counts = 0  # where quick stop and fault reaction hold the motor [counts]
        # Drive time at which the following error left its window [s]; None while inside.
        self.following_error_since: float | None = None

    def reset(self, hold_counts: int) -> None:
        """Power-on, with the motor at ``hold_counts``."""
        self.following_error_since = None
        self.last_controlword = 0
        self.hold_counts = hold_counts
        self.state = SWITCH_ON_DISABLED  # transition 1 is automatic
        self.update_statusword()

    # ----------------------------------------------------------------- live object writes
    def write_controlword(self, controlword: int) -> None:
        """0x6040: run the command it carries."""
        self.values[CONTROLWORD] = controlword
        previous, self.last_controlword = self.last_controlword, controlword
        if controlword & CW_FAULT_RESET:
            # CiA 402: fault reset acts on the rising edge of bit 7, in FAULT only (transition
            # 15); while bit 7 stays set no other command is taken.
            if not previous & CW_FAULT_RESET and self.state == FAULT:
                self.fault_reset()
            return
        for name, mask, value in COMMANDS:
            if controlword & mask == value:
                new_state = TRANSITIONS.get((self.state, name))
                if new_state is not None:
                    self.enter(new_state)
                return

    def write_mode(self, mode: int) -> None:
        """0x6060: a supported mode of operation, displayed at once in 0x6061."""
        if mode not in SUPPORTED_MODES:
            raise SdoAbortedError(ABORT_INVALID_VALUE)
        self.values[MODES_OF_OPERATION] = mode
        self.values[MODES_OF_OPERATION_DISPLAY] = mode
        self.update_statusword()

    # --------------------------------------------------------------------------- states
    def enter(self, new_state: str) -> None:
        if new_state == OPERATION_ENABLED and self.state != QUICK_STOP_ACTIVE:
            # CSP starts from where the motor is (transitions 4 and 3+4, also after a fault
            # reset): no jump when the master's first target lags, no stale target from before
            # a fault (issue 10, item 5).
            position = wrap_int32(self._position_counts())
            self.values[TARGET_POSITION] = position
            self.values[VELOCITY_OFFSET] = 0
            self._on_enable()
        if new_state in (QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE):
            self.hold_counts = self._position_counts()
        self.state = new_state
        self.following_error_since = None
        self.update_statusword()

    def fault(self, code: int, register: int) -> None:
        """Enter FAULT REACTION ACTIVE, set 0x603F / 0x1001 and send the EMCY.

        CiA 402 transition 13: a fault, from any state, starts the fault reaction; the motor is
        held where it is. The drive's next cycle completes the reaction and passes to FAULT
        by itself (transition 14, :meth:`reaction_done`); only a fault reset leaves FAULT.
        """
        if self.state in (FAULT, FAULT_REACTION_ACTIVE):
            return
        self.values[ERROR_CODE] = code
        self.values[ERROR_REGISTER] |= register
        self.enter(FAULT_REACTION_ACTIVE)
        self.emcy.send(code, self.values[ERROR_REGISTER])

    def reaction_done(self) -> None:
        """CiA 402 transition 14: the fault reaction (hold, then power stage off) is complete,
        FAULT REACTION ACTIVE passes to FAULT without a command."""
        if self.state == FAULT_REACTION_ACTIVE:
            self.enter(FAULT)

    def fault_reset(self) -> None:
        """CiA 402 transition 15: a rising edge of controlword bit 7 in FAULT clears the error
        (0x603F, 0x1001, EMCY 0x0000 "error reset") and enters SWITCH ON DISABLED; enabling
        again then starts from the actual position (:meth:`enter`)."""
        self.values[ERROR_CODE] = 0
        self.values[ERROR_REGISTER] = 0
        self.enter(SWITCH_ON_DISABLED)
        self.emcy.send(EMCY_NO_ERROR, 0)

    def update_statusword(self) -> None:
        word = STATUSWORD_OF_STATE[self.state] | SW_REMOTE
        if (self.state == OPERATION_ENABLED
                and self.values[MODES_OF_OPERATION_DISPLAY] == CYCLIC_SYNCHRONOUS_POSITION):
            word |= SW_FOLLOWING_COMMAND
        if self.following_error_since is not None:
            word |= SW_FOLLOWING_ERROR
        self.values[STATUSWORD] = word

    # ------------------------------------------------------------------ following error
    def check_following_error(self, following_error: int, time_s: float) -> None:
        """Flag a following error beyond 0x6065 and fault once it lasted 0x6066 [ms]."""
        window = self.values[FOLLOWING_ERROR_WINDOW]
        beyond = window != FOLLOWING_ERROR_WINDOW_OFF and abs(following_error) > window
        was = self.following_error_since is not None
        if not beyond:
            if was:
                self.following_error_since = None
                self.update_statusword()
            return
        if not was:
            self.following_error_since = time_s
            self.update_statusword()
        timeout_s = self.values[FOLLOWING_ERROR_TIME_OUT] / 1000.0
        if (self.state == OPERATION_ENABLED
                and time_s - self.following_error_since >= timeout_s - 1e-12):
            self.fault(EMCY_FOLLOWING_ERROR, ERROR_REGISTER_GENERIC | ERROR_REGISTER_PROFILE)
