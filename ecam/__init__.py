"""ecam: electronic cams for servo motion controllers.

Motion laws -> cam profiles -> certified fixed-point cam tables. The math core imports no CAN and
no plotting; ``ecam.plot`` and the ``hil_sim`` rig bring those in at the edges.
"""

from . import design, mechanics
from .camfile import load_cam, parse_cam
from .compile import compile_table
from .errors import CamFileError, EcamError, InputError, SimulationError, TableFormatError
from .laws import LAWS, Law, law, polynomial_from_boundary
from .profile import CamProfile, CheckReport, Discontinuity, Segment
from .table import KINDS, CamTable, TableFormat

__version__ = "0.1.0"

__all__ = [
    "CamFileError", "CamProfile", "CamTable", "CheckReport", "Discontinuity", "EcamError", "InputError",
    "KINDS", "LAWS", "Law", "Segment", "SimulationError", "TableFormat", "TableFormatError",
    "compile_table", "design", "law", "load_cam", "mechanics", "parse_cam", "polynomial_from_boundary",
]
