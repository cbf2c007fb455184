"""Hard case (issue 27 item 1): a cross-cutter drum on a 26-bit absolute encoder, asked for one count.

2^26 counts per drum revolution, a net stroke of 360 deg per cut and 2^20 master counts per product.
Written in degrees, 2^26 / 360 counts per degree is a float64 whose decimal product with 360 is
67108864.0000000032: stored as that fraction (denominator 312 500 000), the rounding of k N/D added
up to half a count to every lookup past the first period, and a 1-count tolerance was refused
("the best bound found is 1.03125 counts"). The value meant is 2^26, and that is what is stored.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from ecam import compile_table, load_cam
from ecam.compile import net_stroke_fraction
from tests.test_c_runtime import CLI_SOURCES, STRICT_FLAGS, _compile, c_lookups, write_blob

ROOT = Path(__file__).resolve().parents[1]
DRUM_COUNTS = 2**26
MASTER_COUNTS = 2**20


@pytest.fixture(scope="module")
def knife():
    return load_cam(ROOT / "firmware_tables" / "cams" / "rotary_knife.toml")


def drum(knife, tolerance):
    return compile_table(knife, interp="auto", tolerance=tolerance, master_counts=MASTER_COUNTS,
                         slave_counts_per_unit=DRUM_COUNTS / 360)


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


def test_the_final_rounding_is_nearly_all_that_remains(knife):
    """At a tolerance of 0.55 counts: the final rounding to whole counts costs 1/2, the stored
    positions' 4 fraction bits 1/32, and the interpolation the rest."""
    table = drum(knife, "0.55 counts")
    r = table.report
    assert r["points"] == 129 and r["predicted_error_counts"] <= 0.55
    assert 0.5 <= r["max_error_counts"] <= r["predicted_error_counts"]


def test_the_drum_looks_up_bit_for_bit_in_c(knife, tmp_path):
    table = drum(knife, "1 counts")
    cli = _compile(tmp_path / "ecam_cli", CLI_SOURCES, STRICT_FLAGS)
    rng = np.random.default_rng(27)
    m = table.master_counts
    queries = np.concatenate([
        np.array([0, 1, m - 1, m, -1, -m, 2**31, -(2**31), 2**40 + 3, 2**63 - 1, -(2**63)], dtype=np.int64),
        rng.integers(-5 * m, 5 * m, 20000), rng.integers(-(2**62), 2**62, 2000)]).astype(np.int64)
    position, slope = table.lookup(queries, with_slope=True)
    got = c_lookups(cli, write_blob(tmp_path, "drum.bin", table.to_bytes()), queries)
    expected = np.stack([position.astype(np.int64) & 0xFFFFFFFF, slope], axis=1)
    got[:, 0] &= 0xFFFFFFFF  # the C runtime returns the int32 wrap of a net stroke's position
    assert np.array_equal(got, expected)
