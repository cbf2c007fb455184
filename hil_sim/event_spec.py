"""The ``[[event]]`` tables of a scene, read and checked where they enter (the scene's parser calls
:func:`parse_events`); what they do on the rig is :mod:`hil_sim.events`, which this module leaves
out so that reading a scene loads no ruckig."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ecam.cam_join import COORDINATES
from ecam.validate import Fields, show

__all__ = ["ACTIONS", "ACTIVATIONS", "EVENT_KEYS", "MAX_EVENTS", "START_MODES", "Event", "parse_events"]

#: What an event does.
ACTIONS = ("switch", "offset", "phase", "cam_out")
#: When a switch (or offset) takes effect.
ACTIVATIONS = ("immediate", "period_end", "master_position")
#: How the slave takes a switched cam: at once (a jump where the new cam is elsewhere), or brought
#: onto it by a jerk-limited correction (MC_CamIn StartMode ramp_in, :mod:`hil_sim.ramp_in`).
START_MODES = ("direct", "ramp_in")
#: The keys of an ``[[event]]`` table.
EVENT_KEYS = ("name", "action", "at_period", "at_position", "at_s", "cam", "activation",
              "activation_position", "master", "slave", "master_offset", "slave_offset",
              "master_scaling", "slave_scaling", "allow_jump", "start_mode", "shift",
              "max_velocity", "max_acceleration", "max_jerk")
#: The most events a scene may list.
MAX_EVENTS = 64
#: |offsets|, |shift| and |positions| of events [user units]; scalings are within 1e-6..1e6.
MAX_EVENT_POSITION = 1e12
SCALING_RANGE = (1e-6, 1e6)
_AT_KEYS = ("at_period", "at_position", "at_s")
_LIMIT_KEYS = ("max_velocity", "max_acceleration", "max_jerk")
_SWITCH_KEYS = ("activation", "activation_position", "master", "slave", "master_offset",
                "slave_offset", "master_scaling", "slave_scaling", "allow_jump", "start_mode",
                *_LIMIT_KEYS)
_ACTION_KEYS = {
    "switch": ("cam", *_SWITCH_KEYS),
    "offset": _SWITCH_KEYS,
    "phase": ("shift", *_LIMIT_KEYS),
    "cam_out": _LIMIT_KEYS,
}


@dataclass(frozen=True)
class Event:
    """One ``[[event]]`` of a scene (see the module docstring; units: master units for master
    positions and phase limits, slave units for slave offsets and the cam-out's and a ramp_in
    switch's limits, seconds)."""

    index: int
    action: str
    at_period: int | None = None
    at_position: float | None = None
    at_s: float | None = None
    cam: Path | None = None
    activation: str = "period_end"
    activation_position: float | None = None
    master: str = "absolute"
    slave: str = "absolute"
    master_offset: float = 0.0
    slave_offset: float = 0.0
    master_scaling: float = 1.0
    slave_scaling: float = 1.0
    allow_jump: bool = False
    start_mode: str = "direct"
    shift: float | None = None
    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None
    name: str = ""

    @property
    def label(self) -> str:
        """``event[i] (name)`` for the report."""
        return f"event[{self.index}]" + (f" {self.name}" if self.name else "")


def parse_events(top: Fields, resolve_cam) -> tuple:
    """The scene's ``[[event]]`` tables, checked.

    Parameters
    ----------
    top : ecam.validate.Fields
        The scene's top level.
    resolve_cam : callable
        ``resolve_cam(fields, written)``: the cam file a switch names, resolved as the scene's
        ``cam.file`` is (relative to the scene, or a built-in cam).

    Returns
    -------
    tuple of Event
    """
    raw = top.get("event")
    if raw is None:
        return ()
    if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
        raise top.error(f"event: {show(raw)} should be an array of tables ([[event]])")
    if len(raw) > MAX_EVENTS:
        raise top.error(f"event: {len(raw)} events should be at most {MAX_EVENTS}")
    return tuple(_event(Fields(item, f"event[{i}]", top.source, set(EVENT_KEYS)), i, resolve_cam)
                 for i, item in enumerate(raw))


def _event(r: Fields, index: int, resolve_cam) -> Event:
    action = r.choice("action", ACTIONS, required=True)
    for key in r.raw:
        if key not in ("name", "action", *_AT_KEYS, *_ACTION_KEYS[action]):
            raise r.error(f"{r.name(key)}: does not apply to action {action!r}; expected one of "
                          f"{', '.join(sorted(('name', *_AT_KEYS, *_ACTION_KEYS[action])))}")
    given = [key for key in _AT_KEYS if key in r]
    if len(given) != 1:
        raise r.error(f"{r.where}: {show(given)} should give exactly one of at_period, "
                      "at_position, at_s")
    values = {"index": index, "action": action, "name": r.text("name", default=""),
              "at_period": r.integer("at_period", minimum=0, maximum=2**31),
              "at_position": r.number("at_position", minimum=-MAX_EVENT_POSITION,
                                      maximum=MAX_EVENT_POSITION),
              "at_s": r.number("at_s", minimum=0.0, maximum=1e6)}
    if action == "switch":
        values["cam"] = resolve_cam(r, r.string("cam", required=True))
    if action in ("switch", "offset"):
        values["activation"] = r.choice("activation", ACTIVATIONS, default="period_end")
        if values["activation"] == "master_position":
            values["activation_position"] = r.number("activation_position", required=True,
                                                     minimum=-MAX_EVENT_POSITION,
                                                     maximum=MAX_EVENT_POSITION)
        elif "activation_position" in r:
            raise r.error(f"{r.name('activation_position')}: applies to activation "
                          "'master_position' only")
        values["master"] = r.choice("master", COORDINATES, default="absolute")
        values["slave"] = r.choice("slave", COORDINATES, default="absolute")
        for key in ("master_offset", "slave_offset"):
            values[key] = r.number(key, default=0.0, minimum=-MAX_EVENT_POSITION,
                                   maximum=MAX_EVENT_POSITION)
        for key in ("master_scaling", "slave_scaling"):
            values[key] = r.number(key, default=1.0, minimum=SCALING_RANGE[0],
                                   maximum=SCALING_RANGE[1])
        values["allow_jump"] = r.boolean("allow_jump", default=False)
        values["start_mode"] = r.choice("start_mode", START_MODES, default="direct")
        if values["start_mode"] == "direct":
            for key in _LIMIT_KEYS:
                if key in r:
                    raise r.error(f"{r.name(key)}: applies to start_mode 'ramp_in' only (the "
                                  "correction's limit)")
    if action == "phase":
        values["shift"] = r.number("shift", required=True, minimum=-MAX_EVENT_POSITION,
                                   maximum=MAX_EVENT_POSITION)
    if action in ("phase", "cam_out") or values.get("start_mode") == "ramp_in":
        for key in _LIMIT_KEYS:
            values[key] = r.number(key, required=True, minimum=0.0, maximum=1e15, strict=True)
    return Event(**values)
