"""The protocol state machines of the virtual drive, as data: NMT (CiA 301) and the CiA 402
power state machine (statusword per state, controlword commands, transitions).

Kept apart from :mod:`hil_sim.drive` (which applies them) so the tables read as the standard
prints them, and so other tools and tests can use them without a drive.
"""

# NMT (CiA 301): state codes as sent in the heartbeat, and the commands of the NMT master.
INITIALISING, STOPPED, OPERATIONAL, PRE_OPERATIONAL = 0x00, 0x04, 0x05, 0x7F
NMT_STATE_NAMES = {INITIALISING: "INITIALISING", STOPPED: "STOPPED",
                   OPERATIONAL: "OPERATIONAL", PRE_OPERATIONAL: "PRE-OPERATIONAL"}
#: NMT command specifier -> (new state, reset): reset is None, "application" or "communication".
NMT_COMMANDS = {
    0x01: (OPERATIONAL, None),
    0x02: (STOPPED, None),
    0x80: (PRE_OPERATIONAL, None),
    0x81: (PRE_OPERATIONAL, "application"),
    0x82: (PRE_OPERATIONAL, "communication"),
}

# --------------------------------------------------------------------------------------------
# CiA 402 power state machine, as data.
NOT_READY_TO_SWITCH_ON = "NOT READY TO SWITCH ON"
SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
READY_TO_SWITCH_ON = "READY TO SWITCH ON"
SWITCHED_ON = "SWITCHED ON"
OPERATION_ENABLED = "OPERATION ENABLED"
QUICK_STOP_ACTIVE = "QUICK STOP ACTIVE"
FAULT_REACTION_ACTIVE = "FAULT REACTION ACTIVE"
FAULT = "FAULT"

#: Statusword bits 0-6 of each state (CiA 402 table 30, with bit 4 "voltage enabled" and bit 5
#: "quick stop" as a drive with its power stage on reports them).
STATUSWORD_OF_STATE = {
    NOT_READY_TO_SWITCH_ON: 0x0000,
    SWITCH_ON_DISABLED: 0x0040,
    READY_TO_SWITCH_ON: 0x0031,
    SWITCHED_ON: 0x0033,
    OPERATION_ENABLED: 0x0037,
    QUICK_STOP_ACTIVE: 0x0017,
    FAULT_REACTION_ACTIVE: 0x001F,
    FAULT: 0x0008,
}
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_FOLLOWING_COMMAND = 1 << 12   # CSP: the drive follows the target
SW_FOLLOWING_ERROR = 1 << 13     # CSP: following error beyond the window
CW_FAULT_RESET = 1 << 7

#: Controlword commands (CiA 402 table 28): name, mask, value; the first match wins. A set
#: fault-reset bit (7) masks them all (it is handled as an edge, see TRANSITIONS).
COMMANDS = (
    ("disable_voltage", 0x0002, 0x0000),
    ("quick_stop", 0x0006, 0x0002),
    ("shutdown", 0x0007, 0x0006),
    ("switch_on", 0x000F, 0x0007),
    ("enable_operation", 0x000F, 0x000F),
)

#: (state, command) -> new state; the CiA 402 transition numbers are in the comments.
TRANSITIONS = {
    (SWITCH_ON_DISABLED, "shutdown"): READY_TO_SWITCH_ON,           # 2
    (READY_TO_SWITCH_ON, "switch_on"): SWITCHED_ON,                 # 3
    (READY_TO_SWITCH_ON, "enable_operation"): OPERATION_ENABLED,    # 3 + 4
    (SWITCHED_ON, "enable_operation"): OPERATION_ENABLED,           # 4
    (OPERATION_ENABLED, "switch_on"): SWITCHED_ON,                  # 5
    (SWITCHED_ON, "shutdown"): READY_TO_SWITCH_ON,                  # 6
    (READY_TO_SWITCH_ON, "disable_voltage"): SWITCH_ON_DISABLED,    # 7
    (READY_TO_SWITCH_ON, "quick_stop"): SWITCH_ON_DISABLED,         # 7
    (OPERATION_ENABLED, "shutdown"): READY_TO_SWITCH_ON,            # 8
    (OPERATION_ENABLED, "disable_voltage"): SWITCH_ON_DISABLED,     # 9
    (SWITCHED_ON, "disable_voltage"): SWITCH_ON_DISABLED,           # 10
    (SWITCHED_ON, "quick_stop"): SWITCH_ON_DISABLED,                # 10
    (OPERATION_ENABLED, "quick_stop"): QUICK_STOP_ACTIVE,           # 11
    (QUICK_STOP_ACTIVE, "disable_voltage"): SWITCH_ON_DISABLED,     # 12
    (QUICK_STOP_ACTIVE, "enable_operation"): OPERATION_ENABLED,     # 16
    (FAULT, "fault_reset"): SWITCH_ON_DISABLED,                     # 15
}
# Transitions without a command: 0 and 1 at power-on (NOT READY TO SWITCH ON, then SWITCH ON
# DISABLED), 13 on a fault from any state (FAULT REACTION ACTIVE), 14 when the fault reaction is
# complete (FAULT). The drive applies them itself (hil_sim.drive.power_state).
#: States in which the power stage drives the motor.
ENERGIZED = frozenset({OPERATION_ENABLED, QUICK_STOP_ACTIVE, FAULT_REACTION_ACTIVE})

CYCLIC_SYNCHRONOUS_POSITION = 8
SUPPORTED_MODES = frozenset({0, CYCLIC_SYNCHRONOUS_POSITION})
