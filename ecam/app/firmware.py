"""Generate firmware_tables/: the seed cams' tables, golden vectors and vendor exports, byte for byte
reproducible (no dates: a format version and a content CRC instead).

    python3 -m ecam.app.firmware [DIR]    # default: the repository's firmware_tables/
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ecam.atomic_files import write_files
from ecam.camfile import load_cam
from ecam.compile import compile_table
from ecam.errors import InputError
from ecam.export import export_cam, json_safe, to_c_header, to_json
from ecam.table import KINDS

#: The repository's firmware_tables/: what this module generates, and what the bench builds and
#: runs the C runtime from (the application's one name for it).
FIRMWARE_DIR = Path(__file__).resolve().parents[2] / "firmware_tables"
VECTOR_SEED = 20261121
# Vendor exports of every seed cam (format, interpolation), at this share of the cam's stroke.
EXPORTS = (("codesys", None), ("twincat-cnc", "linear"), ("twincat-cnc", "cubic"), ("kollmorgen", None),
           ("elmo", None), ("technosoft", None), ("csv", "linear"), ("csv", "cubic"), ("csv", "quintic"))
EXPORT_TOLERANCE = 1e-4  # of the stroke
# Hard cases with golden vectors of their own (vectors/STEM.bin, .csv): the cross-cutter drum of
# issue 27 on a 26-bit and a 30-bit encoder (2^B counts per revolution, 360 deg of net stroke per
# cut, 2^20 master counts), stored relative to its ramp (format version 3).
HARD_CASES = (
    ("cross_cutter_drum26_quintic", "rotary_knife",
     {"interp": "quintic", "points": 65, "master_counts": 2**20, "slave_counts_per_unit": 2**26 / 360}),
    # the 26-bit drum at a 1-count tolerance with interpolation_tolerance = "0.05 counts": the
    # 129 points the compiler picks (certified 0.516, measured 0.501 counts; docs/table_formats.md)
    ("cross_cutter_drum26_129_quintic", "rotary_knife",
     {"interp": "quintic", "points": 129, "master_counts": 2**20, "slave_counts_per_unit": 2**26 / 360}),
    ("cross_cutter_drum30_cubic", "rotary_knife",
     {"interp": "cubic", "points": 257, "master_counts": 2**20, "slave_counts_per_unit": 2**30 / 360}),
)


def golden_queries(table) -> np.ndarray:
    """Master counts for golden vectors: edges, wraps, negative and huge values, and a fixed
    random sample."""
    m = table.master_counts
    h = table.format.step_counts
    edges = [0, 1, h - 1, h, h + 1, m - 1, m, m + 1, -1, -h, -m, -m - 1, 2**31 - 1, 2**31, -(2**31), 2**32,
             2**32 + 1, -(2**32), 2**40 + 12345, -(2**40) - 7, 2**62, -(2**62), 2**63 - 1, -(2**63)]
    rng = np.random.default_rng(VECTOR_SEED)
    sample = rng.integers(-4 * m, 5 * m, 2000)
    return np.concatenate([np.array(edges, dtype=np.int64), sample.astype(np.int64)])


def vectors_csv(table) -> str:
    queries = golden_queries(table)
    position, slope = table.lookup(queries, with_slope=True)
    rows = ["master_counts,position,slope"]
    rows += [f"{int(q)},{int(p)},{int(s)}" for q, p, s in zip(queries, position, slope)]
    return "\n".join(rows) + "\n"


def generate(cams_dir: Path) -> dict[str, bytes]:
    """Every generated file, by path relative to firmware_tables/."""
    files: dict[str, bytes] = {}
    for cam_path in sorted(cams_dir.glob("*.toml")):
        profile = load_cam(cam_path)
        stem = cam_path.stem
        table = compile_table(profile)  # the cam file's own [table] format
        files[f"tables/{stem}.h"] = to_c_header(table, stem).encode()
        files[f"tables/{stem}.bin"] = table.to_bytes()
        files[f"tables/{stem}.json"] = to_json(table, stem).encode()
        for kind in KINDS:
            fixed = compile_table(profile, interp=kind, points=table.points, certify=False)
            files[f"vectors/{stem}_{kind}.bin"] = fixed.to_bytes()
            files[f"vectors/{stem}_{kind}.csv"] = vectors_csv(fixed).encode()
        files.update(vendor_exports(profile, stem))
    for stem, cam, settings in HARD_CASES:
        table = compile_table(load_cam(cams_dir / f"{cam}.toml"), **settings, certify=False)
        files[f"vectors/{stem}.bin"] = table.to_bytes()
        files[f"vectors/{stem}.csv"] = vectors_csv(table).encode()
    return files


def vendor_exports(profile, stem: str) -> dict[str, bytes]:
    """exports/STEM.FORMAT[-INTERP].EXT for every vendor format at 1e-4 of the stroke, and
    exports/STEM.certificates.json with every export's certificate."""
    low, high = profile.slave_range
    tolerance = float(f"{EXPORT_TOLERANCE * (high - low):.6g}")
    files: dict[str, bytes] = {}
    certificates = []
    for fmt, interp in EXPORTS:
        label = fmt if interp is None else f"{fmt}-{interp}"
        try:
            result = export_cam(profile, fmt, tolerance=tolerance, interp=interp, name=stem)
        except InputError as exc:
            if not profile.net_stroke:
                raise
            # a format that cannot carry a net stroke: its refusal, with the reason, is the record
            certificates.append({"format": fmt, "interp": interp, "refused": str(exc)})
            continue
        relative = f"exports/{stem}.{label}{result.suffix}"
        files[relative] = result.content.encode()
        summary = result.summary()
        summary["file"] = relative
        certificates.append(summary)
    document = {"cam": stem, "tolerance_units": tolerance, "tolerance_share_of_stroke": EXPORT_TOLERANCE,
                "exports": certificates}
    files[f"exports/{stem}.certificates.json"] = (json.dumps(json_safe(document), indent=1, sort_keys=True)
                                                  + "\n").encode()
    return files


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    root = Path(argv[0]) if argv else FIRMWARE_DIR
    contents = {root / relative: content for relative, content in generate(root / "cams").items()}
    for path in contents:
        path.parent.mkdir(parents=True, exist_ok=True)
    write_files(contents)  # all tables and vectors appear together, or none changes
    for path in contents:
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
