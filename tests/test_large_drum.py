"""Hard case (issue 27 item 1): a cross-cutter drum on a 26-bit absolute encoder, asked for one count.

2^26 counts per drum revolution, a net stroke of 360 deg per cut and 2^20 master counts per product.
Written in degrees, 2^26 / 360 counts per degree is a float64 whose decimal product with 360 is
67108864.0000000032: stored as that fraction (denominator 312 500 000), the rounding of k N/D added
up to half a count to every lookup past the first period, and a 1-count tolerance was refused
("the best bound found is 1.03125 counts"). The value meant is 2^26, and that is what is stored.

Stored as they are, positions of up to 2^26 counts keep 5 fraction bits in int32 and those of 2^30
none (a 1-count tolerance was refused: "the best bound found is 1.00002 counts"). Format version 3
stores the data relative to the net stroke's ramp S m (S = 64 counts per master count here), whose
deviation keeps 9 fraction bits at 2^26 and 5 at 2^30 (FORMAT.md step 8).
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from ecam import compile_table, load_cam
from ecam.compile import net_stroke_fraction
from ecam.table import narrow_horner
from tests.test_c_runtime import CLI_SOURCES, STRICT_FLAGS, _compile, c_lookups, write_blob

ROOT = Path(__file__).resolve().parents[1]
DRUM_COUNTS = 2**26
MASTER_COUNTS = 2**20


@pytest.fixture(scope="module")
def knife():
    return load_cam(ROOT / "firmware_tables" / "cams" / "rotary_knife.toml")


def drum(knife, tolerance, counts=DRUM_COUNTS):
    return compile_table(knife, interp="auto", tolerance=tolerance, master_counts=MASTER_COUNTS,
                         slave_counts_per_unit=counts / 360)


def test_counts_per_degree_of_a_binary_encoder_store_the_whole_revolution():
    assert net_stroke_fraction(360.0, 2**26 / 360) == (Fraction(2**26), pytest.approx(3.2e-9, rel=1e-3))
    assert net_stroke_fraction(360.0, 2**30 / 360)[0] == 2**30
    assert net_stroke_fraction(-360.0, 2**24 / 360)[0] == -(2**24)
    # a decimal that means itself keeps its exact fraction (issue 27 changes only float noise)
    assert net_stroke_fraction(360.0, 1000.0001) == (Fraction(90000009, 250), 0.0)
    assert net_stroke_fraction(3.0, 123456.789012345) == (Fraction(370370367037035, 1000000000), 0.0)


def test_one_count_on_a_26_bit_drum(knife):
    table = drum(knife, "1 counts")
    r = table.report
    assert table.net_stroke == DRUM_COUNTS
    assert r["predicted_error_counts"] <= 1.0
    assert r["max_error_counts"] <= r["predicted_error_counts"]
    assert r["wrap_max_error_counts"] <= r["predicted_error_counts"]
    assert (r["interp"], r["points"], r["bytes"]) == ("quintic", 65, 844)  # fits any drive
    # stored relative to the ramp of 64 counts per master count: 9 fraction bits where absolute
    # positions kept 5, so all but the final rounding's 1/2 count of the error is interpolation
    assert (table.format_version, table.format.ramp_slope, table.format.position_bits) == (3, 64, 9)
    assert r["quantization_counts"] < 0.502
    assert r["max_error_counts"] - r["interpolation_error_counts"] <= 0.5 + 2**-9


def test_the_final_rounding_is_nearly_all_that_remains(knife):
    """At a tolerance of 0.55 counts: the final rounding to whole counts costs 1/2, the stored
    data's 9 fraction bits 1/1024, and the interpolation the rest."""
    table = drum(knife, "0.55 counts")
    r = table.report
    assert r["points"] == 129 and r["predicted_error_counts"] <= 0.55
    assert 0.5 <= r["max_error_counts"] <= r["predicted_error_counts"]


def test_one_count_on_a_30_bit_drum(knife):
    """2^30 counts per cut (the largest stroke int32 positions leave a period for): refused before
    version 3, now 129 quintic points at 1 count, and 257 at 0.55 counts, measured 0.516."""
    table = drum(knife, "1 counts", 2**30)
    r = table.report
    assert (table.format_version, table.format.ramp_slope, table.format.position_bits) == (3, 1024, 5)
    assert (r["interp"], r["points"]) == ("quintic", 129) and r["predicted_error_counts"] <= 1.0
    assert r["max_error_counts"] <= r["predicted_error_counts"] and r["wrap_max_error_counts"] <= 1.0
    fine = drum(knife, "0.55 counts", 2**30).report
    assert fine["points"] == 257 and 0.5 <= fine["max_error_counts"] <= fine["predicted_error_counts"] <= 0.55


@pytest.mark.parametrize("counts", (DRUM_COUNTS, 2**30))
def test_a_32_bit_core_runs_the_drum_in_32_bit_words(knife, counts):
    """horner_bits = 32 keeps the position in the expanded form's first word: relative to the
    ramp that is the deviation alone, so the 32-bit format keeps work bits (2^26: 9; it had 4,
    certified 0.870 counts at 129 points; 2^30: 5, it had 0 and 6.92)."""
    table = compile_table(knife, interp="quintic", points=129, master_counts=MASTER_COUNTS,
                          slave_counts_per_unit=counts / 360, horner_bits=32, certify=False)
    assert table.format_version == 3 and narrow_horner(table)
    assert table.certificate.predicted_error_counts < (0.53 if counts == DRUM_COUNTS else 0.92)


def test_the_drum_looks_up_bit_for_bit_in_c(knife, tmp_path):
    cli = _compile(tmp_path / "ecam_cli", CLI_SOURCES, STRICT_FLAGS)
    rng = np.random.default_rng(27)
    for counts, kind, points in ((DRUM_COUNTS, "quintic", 65), (2**30, "cubic", 129), (2**30, "linear", 257)):
        table = compile_table(knife, interp=kind, points=points, master_counts=MASTER_COUNTS,
                              slave_counts_per_unit=counts / 360, certify=False)
        assert table.format_version == 3
        m = table.master_counts
        queries = np.concatenate([
            np.array([0, 1, m - 1, m, -1, -m, 2**31, -(2**31), 2**40 + 3, 2**63 - 1, -(2**63)], dtype=np.int64),
            rng.integers(-5 * m, 5 * m, 20000), rng.integers(-(2**62), 2**62, 2000)]).astype(np.int64)
        position, slope = table.lookup(queries, with_slope=True)
        got = c_lookups(cli, write_blob(tmp_path, "drum.bin", table.to_bytes()), queries)
        expected = np.stack([position.astype(np.int64) & 0xFFFFFFFF, slope], axis=1)
        got[:, 0] &= 0xFFFFFFFF  # the C runtime returns the int32 wrap of a net stroke's position
        assert np.array_equal(got, expected), (counts, kind)
