"""03: a cam file compiled into a certified fixed-point table, looked up with integers only,
written as a C header and a blob that round-trips."""

from pathlib import Path

import numpy as np

import ecam
from ecam.export import to_c_header

HERE = Path(__file__).resolve().parent
cam = ecam.load_cam(HERE / "project" / "cams" / "lift.toml")
table = ecam.compile_table(cam)                       # the cam file's [table]: auto, 2 counts
certificate = table.certificate
print(f"{table.format.interp} table, {table.format.points} points, {len(table.to_bytes())} bytes")
print(f"max error {certificate.max_error_counts:.3f} counts "
      f"(bound {certificate.predicted_error_counts:.3f})")
period = table.format.master_counts                  # master counts per cam period (36864)
masters = np.arange(0, period, period // 8)           # every 45 deg
print("slave counts:", table.lookup(masters).tolist())
again = ecam.CamTable.from_bytes(table.to_bytes())
assert (again.lookup(masters) == table.lookup(masters)).all()
print(to_c_header(table, "lift").splitlines()[0])
