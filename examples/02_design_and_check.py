"""02: a cam built in Python, segment by segment, checked for jumps, and written as a cam file."""

from ecam import CamProfile, Segment

cam = CamProfile.from_segments([
    Segment.from_span(45.0),                                    # a dwell
    Segment.from_span(135.0, 40.0, "modified_sine", "rise"),
    Segment.from_span(45.0, law="dwell"),
    Segment.from_span(135.0, -40.0, "cycloidal", "return"),
], name="lift", master_unit="deg", slave_unit="mm")

check = cam.check()
print("errors:", len(check.errors), "warnings:", len(check.warnings))
for jump in check.warnings:
    found = jump.to_dict()
    print(f"  {found['quantity']} jumps by {found['jump']:+.4g} at {found['master']} deg ({found['where']})")
print(f"slave at 112.5 deg: {float(cam(112.5)):.3f} mm")
print(cam.to_toml().splitlines()[0])
