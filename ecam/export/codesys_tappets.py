"""The cam's digital cam switches (``[[tappet]]``, :mod:`ecam.tappet`) in a CODESYS SoftMotion
cam: tappet switch actions behind ``MC_CAM_REF.pt``, and the same tracks as switches of
``MC_DigitalCamSwitch`` (which carries what tappet actions cannot: direction-only tracks exactly,
the compensation times and the hysteresis).

What the controller documents:

* CODESYS online help, SM3_Basic, ``MC_CAM_REF`` (FB): ``nTappets`` (INT) "Number of tappet switch
  actions", ``pt`` POINTER TO ``SMC_CAMTappet``.
* CODESYS online help, "Tab: Tappet Table" (cam editor): a tappet is a track ID ("all tappets of a
  tappet path refer to the same tappet switch (a variable of type BOOL)"), a position X, and an
  action for the positive pass and one for the negative pass: "No action", "Switch to ON",
  "Switch to OFF", "Invert" -- the values of ``SMC_CAMTAPPETACTION`` (listed in SM3_Basic).
  ``SMC_GetTappetValue`` reads a track by its group ID ``iID``.
* CODESYS online help, SM3_Basic, ``MC_CAMSWITCH_TR`` (also in Schneider's Machine Expert SM3_Basic
  help): ``TrackNumber`` (INT, 1..32), ``FirstOnPosition``, ``LastOnPosition`` (LREAL),
  ``AxisDirection`` (INT: 0 both, 1 positive, 2 negative), ``CamSwitchMode`` (0: position based),
  ``Duration`` (TIME, time-based switches only).

Not in the documentation this was written from: the member names of ``SMC_CAMTappet`` and the
literal names of ``SMC_CAMTAPPETACTION``. They are written as CODESYS 2.3 SoftMotion named them
(``iGroupID``, ``x``, ``ctaPositive``, ``ctaNegative``; ``TAPPETACTION_NON``, ``_ON``, ``_OFF``):
check them against your SM3_Basic's ``SMC_CAMTappet`` page before use; the export says so in its
header. The compensation times and the hysteresis belong to the track of ``MC_DigitalCamSwitch``
(``MC_TRACK_TR``: OnCompensation, OffCompensation, Hysteresis, as PLCopen's track structure) and
are written in the header comment, per track, for that structure.

Each track becomes two tappet actions (its on and off positions):

=================  ==========================  ==========================
direction          at ``on``: positive / neg.  at ``off``: positive / neg.
=================  ==========================  ==========================
both               ON / OFF                    OFF / ON
positive           ON / OFF                    OFF / no action
negative           no action / OFF             OFF / ON
=================  ==========================  ==========================

so the output is on between the two in the allowed direction, and a master that leaves the window
the other way switches it off. (A master that turns round inside the window passes no tappet: only
``MC_DigitalCamSwitch`` switches a direction-limited track off there.)
"""

from __future__ import annotations

from ecam import validate
from ecam.tappet import DIRECTIONS

from .certify import positional

_ACTIONS = {  # (at on: positive, negative), (at off: positive, negative)
    "both": (("TAPPETACTION_ON", "TAPPETACTION_OFF"), ("TAPPETACTION_OFF", "TAPPETACTION_ON")),
    "positive": (("TAPPETACTION_ON", "TAPPETACTION_OFF"), ("TAPPETACTION_OFF", "TAPPETACTION_NON")),
    "negative": (("TAPPETACTION_NON", "TAPPETACTION_OFF"), ("TAPPETACTION_OFF", "TAPPETACTION_ON")),
}
MAX_TRACKS = 32  # MC_CAMSWITCH_TR.TrackNumber 1..32


def tappet_count(tappets) -> int:
    """``nTappets``: two switch actions per track."""
    return 2 * len(tappets)


def tappet_declarations(tappets, ident: str) -> list[str]:
    """The global variables of the tappets (none without tappets): the tappet actions for
    ``MC_CAM_REF.pt`` and the ``MC_CAMSWITCH_TR`` switches for ``MC_DigitalCamSwitch``."""
    if not tappets:
        return []
    if len(tappets) > MAX_TRACKS:
        raise validate.fail("tappets", f"{len(tappets)} tracks", f"at most {MAX_TRACKS} (MC_CAMSWITCH_TR.TrackNumber)")
    actions = []
    for track_number, track in enumerate(tappets, start=1):
        at_on, at_off = _ACTIONS[track.direction]
        for position, (positive, negative) in ((track.on, at_on), (track.off, at_off)):
            actions.append(f"(iGroupID := {track_number}, x := {positional(position)}, "
                           f"ctaPositive := {positive}, ctaNegative := {negative})")
    switches = [f"(TrackNumber := {k}, FirstOnPosition := {positional(t.on)}, "
                f"LastOnPosition := {positional(t.off)}, AxisDirection := {DIRECTIONS.index(t.direction)}, "
                f"CamSwitchMode := 0, Duration := T#0MS)" for k, t in enumerate(tappets, start=1)]
    lines = [f"    {ident}_tappets : ARRAY[0..{len(actions) - 1}] OF SMC_CAMTappet := ["]
    lines += [f"        {a}{',' if k < len(actions) - 1 else ''}" for k, a in enumerate(actions)]
    lines += ["    ];", f"    {ident}_switches : ARRAY[1..{len(switches)}] OF MC_CAMSWITCH_TR := ["]
    lines += [f"        {s}{',' if k < len(switches) - 1 else ''}" for k, s in enumerate(switches)]
    lines.append("    ];")
    return lines


def tappet_header(tappets, ident: str) -> list[str]:
    """Header comment lines: each track's name and what MC_TRACK_TR needs (compensation,
    hysteresis), and the names to check."""
    if not tappets:
        return []
    lines = [f"   Tappets: {len(tappets)} track(s), {tappet_count(tappets)} switch actions in {ident}_tappets "
             f"(MC_CAM_REF.nTappets, .pt); the same tracks as MC_DigitalCamSwitch switches in {ident}_switches.",
             "   Check SMC_CAMTappet's member names (iGroupID, x, ctaPositive, ctaNegative) against your SM3_Basic."]
    for k, t in enumerate(tappets, start=1):
        lines.append(f"   Track {k}{' ' + repr(t.name) if t.name else ''}: on {t.on:.6g} .. {t.off:.6g}, {t.direction}; "
                     f"MC_TRACK_TR OnCompensation {t.on_compensation:g} s, OffCompensation "
                     f"{t.off_compensation:g} s, Hysteresis {t.hysteresis:g}.")
    return lines
