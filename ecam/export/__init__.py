"""Exporters: pure functions that return text or bytes; only the command line writes files.

Two families:

* ecam's own table (:mod:`.table_files`): a compiled :class:`~ecam.CamTable` as a C header, the
  binary blob, CSV or JSON (``EXPORTERS``, used by ``ecam compile --format``).
* vendor cam tables (:func:`export_cam`): a cam profile as the table a controller users already
  own reads -- CODESYS XYVA, the ISG/TwinCAT CNC table, Kollmorgen KAS, Elmo ET[], Technosoft, CSV
  -- with the point count chosen for a tolerance under that controller's own interpolation and the
  error certified under it (:mod:`.certify`, an :class:`ExportCertificate`). One module per
  format, imported when asked for.

Data exported beside the functions and classes:

* ``EXPORTERS``: ecam's own file formats, ``ecam compile --format`` name -> (file suffix,
  ``exporter(table, name)`` returning text or bytes);
* ``VENDOR_FORMATS``: the vendor formats :func:`export_cam` and ``ecam export --to`` accept, format
  name -> its module in this package (see :func:`vendor_format`).

:func:`json_safe` makes a report JSON-ready (numpy scalars to Python numbers, NaN to None).
"""

from __future__ import annotations

import importlib

from ..errors import InputError
from ..validate import choice, fail
from .certify import Cam, ExportCertificate, VendorExport, check_points, tolerance_units
from .table_files import EXPORTERS, identifier, json_safe, to_blob, to_c_header, to_csv, to_json

__all__ = [
    "to_c_header", "to_blob", "to_csv", "to_json", "EXPORTERS", "identifier", "json_safe",
    "VENDOR_FORMATS", "export_cam", "vendor_format", "VendorExport", "ExportCertificate",
]

# Deprecated alias, kept for one release: this was ``ecam.export.Certificate``, which shadowed
# ecam.Certificate (the table's certificate) under ``from ecam.export import *``. Not in __all__.
Certificate = ExportCertificate

# format name -> module (imported lazily, as python-can imports its interfaces)
VENDOR_FORMATS = {
    "codesys": "codesys",
    "twincat-cnc": "twincat_cnc",
    "kollmorgen": "kollmorgen",
    "elmo": "elmo",
    "technosoft": "technosoft",
    "csv": "csv_points",
}


def vendor_format(name: str):
    """The module of a vendor format (its NAME, SUFFIX, LIMIT, INTERPOLATIONS, CARRIES, RULE and
    ``export``)."""
    choice("format", name, VENDOR_FORMATS)
    return importlib.import_module(f".{VENDOR_FORMATS[name]}", __name__)


def export_cam(profile, format: str, *, tolerance=None, points=None, interp=None, master_counts=None,
               slave_counts_per_unit=None, name=None) -> VendorExport:
    """A cam table for a controller, certified under the controller's own interpolation.

    Parameters
    ----------
    profile : CamProfile
    format : str
        One of ``VENDOR_FORMATS``: codesys, twincat-cnc, kollmorgen, elmo, technosoft, csv.
    tolerance : float or str, optional
        Largest allowed error: slave user units, or a string such as ``"2 counts"``. The fewest
        points within the format's limit that meet it are chosen. Default: the cam file's
        ``[table]`` tolerance.
    points : int, optional
        Instead of a tolerance: this many points (rows / table entries).
    interp : str, optional
        For formats with a choice (twincat-cnc: linear, cubic; csv: linear, cubic, quintic); the
        first is the default.
    master_counts, slave_counts_per_unit : optional
        The cam's counts (default: the cam file's ``[table]``): errors are reported in slave counts
        too, and the Elmo and Technosoft tables are in counts.
    name : str, optional
        Name in the file (default: the cam's name).

    Returns
    -------
    VendorExport
        ``content`` (the file), ``points``, ``certificate`` (predicted bound and measured maximum
        error under the consumer's interpolation, worst plausible reading where its documentation
        leaves the interpolation open), ``notes`` (what to set on the controller).

    Raises
    ------
    InputError
        A bad argument; a net-stroke cam the format cannot express (with the reason).
    TableFormatError
        A tolerance no table within the format's limit meets: one line with the best reachable
        error and the limit.
    """
    module = vendor_format(format)
    cam = Cam(profile, master_counts=master_counts, slave_counts_per_unit=slave_counts_per_unit)
    interp = module.INTERPOLATIONS[0] if interp is None else choice("interp", interp, module.INTERPOLATIONS)
    if points is not None and tolerance is not None:
        raise fail("points", points, "given without a tolerance (give points or tolerance, not both)")
    if points is None and tolerance is None:
        tolerance = (profile.table or {}).get("tolerance")
        if tolerance is None:
            raise InputError("tolerance: missing; expected --tolerance X (slave units, or 'N counts') or --points N")
    if points is not None:
        points = check_points(points, module.MIN_POINTS, module.LIMIT)
        tol = None
    else:
        tol = tolerance_units(tolerance, cam)
    return module.export(cam, tolerance=tol, points=points, interp=interp,
                         name=name if name is not None else (profile.name or "cam"))
