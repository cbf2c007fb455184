"""ecam: electronic cams for servo motion controllers."""
from .errors import EcamError, InputError, CamFileError, TableFormatError, SimulationError
from .laws import LAWS, Law, law, polynomial_from_boundary

__version__ = "0.1.0"
from .profile import CamProfile, Segment, CheckReport, Discontinuity
from .camfile import load_cam, parse_cam
from . import design, mechanics
from .table import CamTable, TableFormat, KINDS
from .compile import compile_table
