"""ecam: electronic cams for servo motion controllers.

Motion laws -> cam profiles -> certified fixed-point cam tables. The math core imports no CAN and
no plotting; ``ecam.plot`` and the ``hil_sim`` rig bring those in at the edges.

A cam from Python, segment by segment (spans and strokes; positions add up from 0)::

    import ecam
    from ecam import CamProfile, Segment

    cam = CamProfile.from_segments([
        Segment.from_span(60.0),                                   # a dwell
        Segment.from_span(120.0, 10.0, "modified_sine", "rise"),
        Segment.from_span(60.0),
        Segment.from_span(120.0, -10.0, "cycloidal", "return"),
    ], name="knife")
    cam.check().ok                  # continuity at every joint and at the seam
    text = cam.to_toml()            # a cam file that ecam.parse_cam / ecam.load_cam read back equal
    table = ecam.compile_table(cam, interp="cubic", points=361, master_counts=36000)

Every bad value raises one line, ``<field>: <value> should be <expected>``, as an
:class:`InputError` (a ``ValueError``); a cam file's errors are :class:`CamFileError` and name
the file and its field.

Data exported beside the functions and classes:

* ``LAWS``: the rise laws by name (name -> :class:`Law`); ``DWELL``: the dwell law (s = 0), which
  :func:`law` and cam files accept as ``"dwell"``; ``LAW_NAMES``: every name :func:`law`
  accepts, sorted (the rise laws and ``"dwell"``).
* ``KINDS``: the table interpolation kinds and their polynomial degree (linear 1, cubic 3,
  quintic 5); ``INTERPOLATIONS``: every ``interp`` a :class:`TableSpec` accepts (the kinds and
  ``"auto"``).

Cams from points: :func:`fit_points` (a quintic smoothing spline, jerk continuous, its deviation
certified; :mod:`ecam.points` reads point tables) gives a cam of one ``law = "spline"`` segment.

Submodules: :mod:`ecam.design` (combination curves, modified-sine and dwell-rise-return-dwell
cams), :mod:`ecam.mechanics` (:class:`Mechanics`, reflected inertia, the two-mass mode, the
coupling checks), :mod:`ecam.export` (C header, blob, CSV, JSON, vendor tables; imported on
its own), :mod:`ecam.plot` (the motion diagram; the only core module that imports matplotlib).
"""

from . import design, mechanics
from .camfile import load_cam, parse_cam
from .certificate import Certificate, Measurement
from .compile import compile_table
from .errors import CamFileError, EcamError, InputError, SimulationError, TableFormatError
from .fit import FitResult, fit_points
from .laws import DWELL, LAW_NAMES, LAWS, Law, law, polynomial_from_boundary
from .mechanics import Mechanics
from .profile import CamProfile, CheckReport, Discontinuity, Segment
from .table import INTERPOLATIONS, KINDS, CamTable, TableFormat
from .table_spec import TableSpec

__version__ = "0.1.0"

__all__ = [
    "CamFileError", "CamProfile", "CamTable", "Certificate", "CheckReport", "DWELL", "Discontinuity", "EcamError", "InputError",
    "INTERPOLATIONS", "KINDS", "LAWS", "LAW_NAMES", "Law", "Measurement", "Mechanics", "Segment", "SimulationError", "TableFormat", "TableFormatError", "TableSpec",
    "FitResult", "compile_table", "design", "fit_points", "law", "load_cam", "mechanics", "parse_cam", "polynomial_from_boundary",
]
