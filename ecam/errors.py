"""The one exception tree of ecam.

Every error a user can cause derives from :class:`EcamError`; errors about a bad value also
derive from :class:`ValueError`, so callers may catch either. Messages name the field, the value
and the limit, in one line.
"""


class EcamError(Exception):
    """Base class of every error raised by ecam and hil_sim."""


class InputError(EcamError, ValueError):
    """A value given by the user is out of its allowed range or of the wrong type."""


class CamFileError(InputError):
    """A cam or scene file is malformed."""


class TableFormatError(InputError):
    """A table format cannot be built (overflow, point count, tolerance) or a blob is invalid."""


class SimulationError(EcamError):
    """The simulation rig could not run a scene."""
