"""04: the cam as a CODESYS XYVA table, certified under the controller's own interpolation."""

from pathlib import Path

import ecam
from ecam.export import export_cam

HERE = Path(__file__).resolve().parent
cam = ecam.load_cam(HERE / "project" / "cams" / "lift.toml")
result = export_cam(cam, "codesys", tolerance="2 counts")
summary = result.summary()
print(f"{summary['format']}: {summary['points']} points, "
      f"max error {summary['max_error_units']:.6f} mm (bound {summary['predicted_error_units']:.6f})")
print(result.content.splitlines()[0])
