"""CODESYS SoftMotion: an XYVA cam as IEC 61131-3 source (a global variable list).

What the controller does with it, from its documentation:

* CODESYS online help, SM3_Basic, ``SMC_CAM_TYPE`` (Enum): "XYVA 3: Polynomial description
  consisting of master position X, slave position Y, slave velocity V and slave acceleration A".
* Lenze PLC Designer SoftMotion manual (CODESYS SoftMotion inside), section 5.7.2 ``SMC_CAMXYVA``:
  "An XYVA cam consists of an array of SMC_CAMXYVA. Each variable of that array describes a point
  on the cam using dX (master position), dY (slave position), dV (first derivative dY/dX ...) and
  dA (second derivative d²Y/dX² ...). The start and end points of the cam must always be included."
* CODESYS online help, "Creating Cams Programmatically": the default cam "consists of three
  fifth-degree polynomials with the following four boundary values: X Y V A".
* CODESYS online help, SM3_Basic, ``MC_CAM_REF`` (FB): ``byType`` the cam type, ``xStart``/``xEnd``
  the master range, ``nElements`` (INT) "the number of ... XYVA points", ``pce`` "XYVA: pce points
  to an array of SMC_CAMXYVA".

So between two points the controller runs the one polynomial of degree 5 that takes both points'
Y, V and A: a quintic Hermite polynomial, which is what ecam certifies. The documentation leaves
nothing of it open. The point limit is that of ``nElements`` (INT: 32767); ``SMC_ReadCAM``, which
reads cams from files, takes 128 points unless told otherwise -- this export is source code instead.

The global variable list has the shape of the one CODESYS generates for a cam itself (CODESYS
online help, "Command: Display Generated Code": ``Cam_A: ARRAY[0..3] OF SMC_CAMXYVA := [(dX := 0,
dY := 0, dV := 0, dA := 0), ...]; Cam: MC_CAM_REF := (nElements := 4, byType := 3, xStart := 0,
xEnd := 360, nTappets := 0, strCAMName := 'Cam', pce := ADR(Cam_A), ...)``).

A cam whose slave ends a net stroke above its start: CODESYS online help, "Function Blocks:
MC_CamTableSelect and MC_CamIn", ``MC_CamIn.StartMode``: "absolute: When starting a new cycle, the
cam is evaluated independent of the current slave position", so the slave jumps back unless it is a
modulo axis whose period divides the net stroke ("Dialog: Properties - Cam", Slave period: "the
slave position at the start and end of the master period may deviate by one integer multiple of
this value"); "relative: ... The position of the slave after the end of the previous cycle is added
as a slave offset to the new evaluation of the cam", with a jump "if the slave position at the
master start position is not 0" -- so relative mode carries a net stroke on any slave axis when the
cam starts at dY = 0. Both settings are named in the export's notes; the table itself is the same.
"""

from __future__ import annotations

import numpy as np

from .certify import (
    EXPORT_VERSION, Cam, Hermite, Reading, VendorExport, certify, content_crc, knot_data, place_local, positional,
)
from .escape import iec_comment
from .codesys_tappets import tappet_count, tappet_declarations, tappet_header
from .table_files import identifier

NAME = "codesys"
SUFFIX = ".st"
LIMIT = 32767  # MC_CAM_REF.nElements is an INT
MIN_POINTS = 2
INTERPOLATIONS = ("quintic",)
CARRIES = "X, Y, V = dY/dX, A = d²Y/dX² (LREAL)"
RULE = "one fifth-degree polynomial per interval through both points' Y, V and A"


def _comment(text: str) -> str:
    """A ``(* ... *)`` comment written above, its inside made safe (:func:`escape.iec_comment`)."""
    return "(* " + iec_comment(text[3:-3]) + " *)"


def export(cam: Cam, *, tolerance, points, interp, name: str) -> VendorExport:
    grid = cam.master_counts  # points on whole master counts
    knots = place_local(cam, 5, grid=grid, tolerance=tolerance, points=points, limit=LIMIT,
                        what="codesys (XYVA)")
    master = knots * (cam.period / grid)
    data = knot_data(cam, master, 3)
    # The file holds the shortest decimal of each float64: the controller reads the very same numbers.
    text_rows = [[positional(v) for v in (x, *row)] for x, row in zip(master, data)]
    hermite = Hermite.continuous(np.array([float(r[0]) for r in text_rows]), 5,
                                 np.array([[float(v) for v in r[1:]] for r in text_rows]))
    certificate = certify(cam, [Reading("XYVA quintic", hermite)], tolerance)

    ident = identifier(name)
    body = [
        "VAR_GLOBAL",
        f"    {ident}_xyva : ARRAY[0..{len(text_rows) - 1}] OF SMC_CAMXYVA := [",
    ]
    for k, (x, y, v, a) in enumerate(text_rows):
        end = "," if k < len(text_rows) - 1 else ""
        body.append(f"        (dX := {x}, dY := {y}, dV := {v}, dA := {a}){end}")
    tappets = cam.profile.tappets  # [[tappet]]: MC_CAM_REF.nTappets / .pt (ecam.export.codesys_tappets)
    tappet_ref = f", pt := ADR({ident}_tappets)" if tappets else ""
    body += [
        "    ];",
        *tappet_declarations(tappets, ident),
        f"    {ident} : MC_CAM_REF := (byType := 3, xStart := {positional(0.0)}, xEnd := {positional(cam.period)}, "
        f"nElements := {len(text_rows)}, nTappets := {tappet_count(tappets)}, pce := ADR({ident}_xyva)"
        f"{tappet_ref}, strCAMName := '{ident}');",
        "END_VAR",
        "",
    ]
    body_text = "\n".join(body)
    unit, munit = cam.profile.slave_unit, cam.profile.master_unit
    c = certificate
    header = [
        f"(* Generated by ecam (vendor export {EXPORT_VERSION}) from cam '{cam.name}'; "
        f"CRC-32 0x{content_crc(body_text):08x} of the lines from VAR_GLOBAL on. Do not edit. *)",
        f"(* CODESYS SoftMotion XYVA cam (MC_CAM_REF.byType 3 = SMC_CAM_TYPE.XYVA), {len(text_rows)} points; "
        f"dX in {munit}, dY in {unit}, dV in {unit}/{munit}, dA in {unit}/{munit}^2.",
        "   Between two points the controller runs the fifth-degree polynomial through both points' dY, dV, dA",
        "   (CODESYS help SMC_CAM_TYPE, MC_CAM_REF; Lenze PLC Designer SoftMotion manual 5.7.2 SMC_CAMXYVA).",
    ]
    notes = [f"select the table with MC_CamTableSelect(CamTable := {ident}, "
             f"Periodic := {'TRUE' if cam.periodic else 'FALSE'})"]
    if cam.net_stroke:
        start = float(data[0, 0])
        relative = ("MC_CamIn.StartMode := relative (MC_CamTableSelect.SlaveAbsolute := FALSE): each period adds "
                    "the slave position reached at the end of the previous one"
                    + ("" if start == 0.0 else f" -- this cam starts at dY = {start:.6g} {unit}, so relative mode "
                       f"would jump by that much every period; use the modulo axis"))
        notes.append(f"net stroke {cam.net_stroke:+.6g} {unit} per period: either StartMode absolute with a modulo "
                     f"slave axis whose period divides {abs(cam.net_stroke):.6g} {unit}, or " + relative)
        header.append(f"   Net stroke {cam.net_stroke:+.6g} {unit} per period (the last point is the first one period "
                      f"on): StartMode absolute on a modulo slave whose period divides it"
                      + (", or StartMode relative (the cam starts at dY = 0)." if start == 0.0 else "."))
    header += tappet_header(tappets, ident)
    header += [
        f"   Certified by ecam under that interpolation: max error {c.max_error_units:.6g} {unit} "
        f"({c.max_error_counts:.6g} counts at {cam.scale:g} counts/{unit}) at master {c.max_error_at_master:.6g} "
        f"{munit};",
        f"   predicted bound {c.predicted_error_units:.6g} {unit}. *)",
    ]
    # The user's text (name, units) goes into the two comments only, and never ends or opens one:
    # each comment's whole inside is escaped, since a unit's "*" after the "/" of "dV in mm/..."
    # makes a delimiter that neither piece holds alone.
    content = _comment(header[0]) + "\n" + _comment("\n".join(header[1:])) + "\n" + body_text
    return VendorExport(NAME, "xyva-quintic", len(text_rows), LIMIT, content, SUFFIX, certificate,
                        master, tuple(notes))
