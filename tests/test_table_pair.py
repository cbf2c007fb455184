"""Queued table switching at a period boundary (issue 23, item 1, firmware side):
firmware_tables/ecam_table_pair.c (ecam_switch_pair) against ecam/table_pair.py (SwitchPair),
bit for bit, over master sequences that cross boundaries both ways; the switch at the boundary
count itself; PLCopen's absolute/relative master and slave; every refusal's code.

The C driver (firmware_tables/targets/switch_check.c) is built once for the module; each script
runs through it and through Python, and every output of every command must be equal.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ecam import CamTable, compile_table, load_cam
from ecam.errors import InputError
from ecam.table_pair import CODES, MASTER_RELATIVE, SLAVE_RELATIVE, SwitchPair, SwitchRefused, mode_flags

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import c_blobs as cb  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware_tables"
DRIVER_SOURCES = ("targets/switch_check.c", "ecam_host_io.c", "ecam_table.c", "ecam_table_pair.c")
# the runtime's strict set (firmware_tables/Makefile), for the new file and its driver
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wconversion", "-Wsign-conversion", "-Wcast-align", "-pedantic",
          "-Werror"]  # fmt: skip
INVALID = -(2**31)  # ECAM_INVALID
INIT, ENGAGE, ARM, CANCEL, STEP = range(5)
BOTH = MASTER_RELATIVE | SLAVE_RELATIVE

# The table pool, by index in the driver's argument list.
DRRD, SINE, KNIFE, KNIFE_Q, SINGLE, TINY_SINGLE, TINY, DRUM, BROKEN = range(9)
PERIODIC = (DRRD, SINE, KNIFE, KNIFE_Q, TINY, DRUM)


def table_pool() -> list[bytes]:
    """Blobs: the golden periodic tables (a net stroke among them), random tables that do not
    repeat, a periodic table of 6 counts (boundaries everywhere), the knife's drum at 2^26 counts
    per turn (format version 3, its data relative to its ramp; int32 wraps every 32 turns) and a
    corrupt blob."""
    vectors = FIRMWARE / "vectors"
    rng = np.random.default_rng(23_2026)
    blobs = [(vectors / f"{stem}.bin").read_bytes() for stem in
             ("combination_drrd_cubic", "modified_sine_quintic", "rotary_knife_linear", "rotary_knife_quintic")]
    blobs.append(cb.make_blob(cb.random_table(rng, 3, False, 3000, 30)))
    blobs.append(cb.make_blob(cb.random_table(rng, 1, False, 7, 7)))
    blobs.append(cb.make_blob(cb.random_table(rng, 5, True, 6, 3)))
    knife = load_cam(FIRMWARE / "cams" / "rotary_knife.toml")
    drum = compile_table(knife, interp="quintic", points=129, master_counts=2**20, slave_counts_per_unit=2**26 / 360,
                         certify=False)  # fmt: skip
    assert drum.format_version == 3
    blobs.append(drum.to_bytes())
    broken = bytearray(blobs[0])
    broken[-1] ^= 0xFF  # payload CRC fails: ecam_table_init leaves the table not ready
    blobs.append(bytes(broken))
    return blobs


def python_tables(blobs: list[bytes]) -> list:
    out = []
    for blob in blobs:
        try:
            out.append(CamTable.from_bytes(blob))
        except InputError:
            out.append("not ready")  # the C table whose init failed: refused as ECAM_SWITCH_E_TABLE
    return out


def command(cmd) -> tuple:
    """A command as the driver's five words (op, a, b, c, d): shorter tuples end in zeros."""
    return tuple(cmd) + (0,) * (5 - len(cmd))


def run_python(script, tables) -> list[tuple]:
    """What switch_check prints for ``script``, computed by SwitchPair."""
    pair, out = SwitchPair(), []
    for op, a, b, c, d in map(command, script):
        table = tables[a] if 0 <= a < len(tables) else None
        rc, position, slope = 0, INVALID, INVALID
        try:
            if op == INIT:
                pair = SwitchPair()
            elif op == ENGAGE:
                pair.engage(table, b, c)
            elif op == ARM:
                pair.arm_mode(table, b, c, d)
            elif op == CANCEL:
                pair.cancel()
            else:
                sample = pair.step(a)
                position, slope, rc = sample.position, sample.slope, int(sample.switched)
        except SwitchRefused as refused:
            rc = refused.code
        out.append((rc, position, slope, pair.boundary, pair.switches, int(pair.pending is not None)))
    return out


def driver_args(directory: Path, script) -> list[str]:
    """Write ``script`` beside the pool's blobs; the driver's arguments (relative to directory)."""
    np.asarray([command(c) for c in script], dtype="<i8").reshape(-1, 5).tofile(directory / "script.i64")
    blobs = sorted(directory.glob("t*.bin"), key=lambda p: int(p.stem[1:]))
    return ["script.i64", "out.i64", *(p.name for p in blobs)]


def read_out(directory: Path) -> list[tuple]:
    return [tuple(int(v) for v in row) for row in np.fromfile(directory / "out.i64", dtype="<i8").reshape(-1, 6)]


def run_c(exe: Path, directory: Path, script) -> list[tuple]:
    proc = subprocess.run([str(exe), *driver_args(directory, script)], cwd=directory, capture_output=True, text=True,
                          timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return read_out(directory)


def write_pool(directory: Path, blobs: list[bytes]) -> None:
    for k, blob in enumerate(blobs):
        (directory / f"t{k}.bin").write_bytes(blob)


def _compiler():
    for name in (os.environ.get("CC", "cc"), "cc", "gcc", "clang"):
        if shutil.which(name):
            return shutil.which(name)
    return None


@pytest.fixture(scope="module")
def pool():
    blobs = table_pool()
    return blobs, python_tables(blobs)


@pytest.fixture(scope="module")
def driver(tmp_path_factory, pool):
    """(run, tables): run(script) -> the C outputs; built once, strict, -O2."""
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    directory = tmp_path_factory.mktemp("switch")
    exe = directory / "switch_check"
    build = subprocess.run([cc, *STRICT, "-O2", "-I", str(FIRMWARE), "-o", str(exe),
                            *(str(FIRMWARE / s) for s in DRIVER_SOURCES)], capture_output=True, text=True)  # fmt: skip
    assert build.returncode == 0 and build.stderr == "", build.stderr
    write_pool(directory, pool[0])
    return (lambda script: run_c(exe, directory, script)), pool[1]


def both(driver, script) -> list[tuple]:
    """The outputs, asserted equal in C and Python."""
    run, tables = driver
    got, expected = run(script), run_python(script, tables)
    assert got == expected
    return got


def steps(masters) -> list[tuple]:
    return [(STEP, int(m), 0, 0) for m in masters]


# ------------------------------------------------------------------------------ the boundary

def test_forwards_the_pending_table_takes_over_at_the_boundary_count_itself(driver):
    """DRRD runs [0, 36864); SINE armed with the master relative: 36863 is still DRRD's,
    36864 (the boundary) already SINE's master 0, then SINE's 1."""
    tables = driver[1]
    M = tables[DRRD].master_counts
    out = both(driver, [(ENGAGE, DRRD, 0, 0), *steps([M - 40, M - 2]), (ARM, SINE, BOTH, 0),
                        *steps([M - 1, M, M + 1])])  # fmt: skip
    rc = [row[0] for row in out]
    assert rc == [0, 0, 0, 0, 0, CODES["ECAM_SWITCH_DONE"], 0]
    assert out[4][1] == tables[DRRD].lookup(M - 1)  # one count early: still the running table
    slave_at_boundary = tables[DRRD].lookup(M)  # relative slave: carried as the offset
    assert out[5][1] == tables[SINE].lookup(0) + slave_at_boundary
    assert out[6][1] == tables[SINE].lookup(1) + slave_at_boundary
    assert out[5][3] == M and out[5][4] == 1 and out[5][5] == 0  # boundary, count, nothing pending
    assert out[3][5] == 1 and out[4][5] == 1  # pending until the boundary


def test_backwards_the_boundary_count_stays_with_the_running_table(driver):
    """The master running back through DRRD's period start: 0 is still DRRD's; -1 is the first
    count of the period below, the pending table's (master relative: its master -1, which wraps
    to its period end)."""
    tables = driver[1]
    out = both(driver, [(ENGAGE, DRRD, 0, 0), *steps([30, 2]), (ARM, SINE, BOTH, 0), *steps([1, 0, -1, -2])])
    assert [row[0] for row in out[4:]] == [0, 0, CODES["ECAM_SWITCH_DONE"], 0]
    assert out[5][1] == tables[DRRD].lookup(0) and out[5][5] == 1  # the boundary count: still DRRD's
    assert out[6][3] == 0  # the boundary crossed: the period start
    offset = tables[DRRD].lookup(0)
    assert out[6][1] == tables[SINE].lookup(-1) + offset == tables[SINE].lookup(tables[SINE].master_counts - 1) + offset
    assert out[7][1] == tables[SINE].lookup(-2) + offset


def test_with_nothing_armed_the_pair_is_the_table(driver):
    """Master and slave offsets as MC_CamIn applies them: the table at master + MasterOffset,
    plus SlaveOffset; many periods both ways, no switch."""
    tables = driver[1]
    masters = list(range(-200_000, 200_000, 997))
    out = both(driver, [(ENGAGE, KNIFE, 1234, -77), *steps(masters)])
    expected = [cb.int32_wrap(tables[KNIFE].lookup(m + 1234) - 77) for m in masters]
    assert [row[1] for row in out[1:]] == expected and {row[0] for row in out[1:]} == {0}


def test_a_jump_over_several_periods_switches_at_the_first_boundary(driver):
    tables = driver[1]
    M = tables[DRRD].master_counts
    out = both(driver, [(ENGAGE, DRRD, 0, 0), *steps([5]), (ARM, SINE, MASTER_RELATIVE, 0), *steps([3 * M + 7])])
    assert out[-1][0] == CODES["ECAM_SWITCH_DONE"] and out[-1][3] == M
    assert out[-1][1] == tables[SINE].lookup(2 * M + 7)  # relative master: SINE's 0 at M; absolute slave
    back = both(driver, [(ENGAGE, DRRD, 0, 0), *steps([5]), (ARM, SINE, MASTER_RELATIVE, 0), *steps([-3 * M])])
    assert back[-1][3] == 0


# ------------------------------------------------------------------------------ PLCopen coordinates

def test_a_relative_switch_of_the_knife_to_itself_changes_no_count(driver):
    """The rotary knife advances 360000 counts per period (net stroke). Switched to itself with
    master and slave relative after three periods, it continues exactly as if never switched;
    the slave absolute restarts it at 0 (ecam check --then reports that -360 deg jump); master
    and slave absolute are its own coordinates, so nothing changes either."""
    tables = driver[1]
    M = tables[KNIFE].master_counts
    masters = list(range(3 * M - 5, 3 * M + 6))
    plain = [row[1] for row in both(driver, [(ENGAGE, KNIFE, 0, 0), *steps(masters)])[1:]]
    for mode, jump in ((BOTH, 0), (0, 0), (MASTER_RELATIVE, -3 * 360_000)):
        out = both(driver, [(ENGAGE, KNIFE, 0, 0), *steps([3 * M - 9]), (ARM, KNIFE, mode, 0), *steps(masters)])
        got = [row[1] for row in out[3:]]
        assert got[:5] == plain[:5]
        assert [g - p for g, p in zip(got[5:], plain[5:])] == [jump] * 6, mode
        assert out[8][0] == CODES["ECAM_SWITCH_DONE"] and out[8][3] == 3 * M


def test_the_drum_switched_relatively_past_the_int32_wrap_changes_no_count(driver):
    """The knife's drum at 2^26 counts per turn (format version 3): after 40 turns its position
    has wrapped int32 (at 32 turns); switched to itself with master and slave relative, the
    offset carried modulo 2^32 keeps every count of the unswitched drum."""
    M = driver[1][DRUM].master_counts
    masters = [40 * M + d for d in (-3, -1, 0, 1, 5000)]
    plain = [row[1] for row in both(driver, [(ENGAGE, DRUM, 0, 0), *steps(masters)])[1:]]
    out = both(driver, [(ENGAGE, DRUM, 0, 0), *steps([40 * M - 9]), (ARM, DRUM, BOTH), *steps(masters)])
    assert [row[1] for row in out[3:]] == plain and out[5][0] == CODES["ECAM_SWITCH_DONE"]
    assert plain[2] == cb.int32_wrap(40 * 2**26)  # the turns' stroke, wrapped


def test_a_relative_slave_is_continuous_into_a_cam_that_starts_at_zero(driver):
    """DRRD -> SINE at DRRD's period end, both starting at 0: with the slave relative the slave
    position at the boundary is DRRD's there, and the positions around it move by no more than
    either table moves per count elsewhere."""
    tables = driver[1]
    M = tables[DRRD].master_counts
    masters = list(range(2 * M - 50, 2 * M + 50))
    out = both(driver, [(ENGAGE, DRRD, 0, 1000), *steps([2 * M - 60]), (ARM, SINE, BOTH, 0), *steps(masters)])
    positions = np.array([row[1] for row in out[3:]])
    assert positions[50] == tables[DRRD].lookup(2 * M) + 1000  # the boundary: DRRD's position there
    largest = max(int(np.abs(np.diff(tables[k].lookup(np.arange(-2, tables[k].master_counts + 2)))).max())
                  for k in (DRRD, SINE))  # fmt: skip
    assert int(np.abs(np.diff(positions)).max()) <= largest


def test_master_absolute_enters_the_pending_table_at_the_master_position(driver):
    """Master absolute: SINE is looked up at master + MasterOffset (CODESYS: "started at the
    current master position"), mid-period when the periods differ; slave absolute: plus
    SlaveOffset (both the switch's, here the engagement's again)."""
    tables = driver[1]
    M = tables[DRRD].master_counts
    out = both(driver, [(ENGAGE, DRRD, 100, 5), *steps([M - 101]), (ARM, SINE, 0, 100, 5), *steps([M - 100, M - 99])])
    assert out[3][0] == CODES["ECAM_SWITCH_DONE"] and out[3][3] == M - 100
    assert [out[3][1], out[4][1]] == [tables[SINE].lookup(M) + 5, tables[SINE].lookup(M + 1) + 5]


def test_each_switch_brings_its_own_mc_camin_offsets(driver):
    """A switch is a new MC_CamIn: X = master - zero + MasterOffset, Y = CAM(X) + SlaveOffset +
    base. Relative master and slave with offsets (500, -3): SINE entered at its 500, on top of
    the slave's position at the boundary, minus 3; then DRRD absolute with (-20, 9): DRRD at
    master - 20, plus 9, whatever came before."""
    tables = driver[1]
    M, S = tables[DRRD].master_counts, tables[SINE].master_counts
    script = [(ENGAGE, DRRD, 0, 7), *steps([M - 1]), (ARM, SINE, BOTH, 500, -3), *steps([M, M + S - 501]),
              (ARM, DRRD, 0, -20, 9), *steps([M + S - 500, M + S - 499])]  # fmt: skip
    out = both(driver, script)
    at = tables[DRRD].lookup(M) + 7
    assert out[3][0] == CODES["ECAM_SWITCH_DONE"] and out[3][1] == tables[SINE].lookup(500) + at - 3
    assert out[4][1] == tables[SINE].lookup(S - 1) + at - 3
    assert out[-2][0] == CODES["ECAM_SWITCH_DONE"] and out[-2][3] == M + S - 500 and out[-2][4] == 2
    assert [out[-2][1], out[-1][1]] == [tables[DRRD].lookup(M + S - 520) + 9, tables[DRRD].lookup(M + S - 519) + 9]


def test_the_firmware_jumps_as_ecam_check_predicts(driver):
    """The knife switched to itself at its first period end: the position jump in counts is
    ecam.cam_join's (`ecam check --then`) times the table's counts per degree in all four
    placements. With the master absolute both evaluate the table at the master position with the
    net stroke of the period before: no jump with the slave absolute, the slave's position at the
    boundary (+360 deg) with it relative; with the master relative a restart at 0 (-360 deg) and
    no jump (tests/test_switch_rule.py: the same for a pair of net strokes, the rig included)."""
    from ecam.cam_join import join_cams

    table = driver[1][KNIFE]
    cam = load_cam(ROOT / "ecam" / "cams" / "rotary_knife.toml")
    per_unit = table.net_stroke / cam.net_stroke  # slave counts per degree
    assert per_unit == 1000
    M = table.master_counts
    jumps = {}
    for master in ("absolute", "relative"):
        for slave in ("absolute", "relative"):
            out = both(driver, [(ENGAGE, KNIFE, 0, 0), *steps([M - 1]), (ARM, KNIFE, mode_flags(master, slave)),
                                *steps([M])])  # fmt: skip
            assert out[-1][0] == CODES["ECAM_SWITCH_DONE"]
            join = join_cams(cam, cam, master=master, slave=slave)
            jumps[master, slave] = (out[-1][1] - table.lookup(M), round((join.right[0] - join.left[0]) * per_unit))
    assert jumps["relative", "absolute"] == (-360_000, -360_000)
    assert jumps["relative", "relative"] == (0, 0)
    assert jumps["absolute", "absolute"] == (0, 0)
    assert jumps["absolute", "relative"] == (360_000, 360_000)


# ------------------------------------------------------------------------------ tables that do not repeat

def test_a_table_that_does_not_repeat_switches_where_its_profile_ends(driver):
    """SINGLE covers [0, 3000): crossing 3000 is its end (the boundary); armed after the master
    left its range, the pending table takes over at the next sample, there."""
    tables = driver[1]
    out = both(driver, [(ENGAGE, SINGLE, 0, 0), *steps([2990]), (ARM, SINE, BOTH, 0), *steps([2999, 3004])])
    assert out[-1][0] == CODES["ECAM_SWITCH_DONE"] and out[-1][3] == 3000
    assert out[-1][1] == cb.int32_wrap(tables[SINE].lookup(4) + tables[SINGLE].lookup(3000))
    late = both(driver, [(ENGAGE, SINGLE, 0, 0), *steps([2990, 5000, 6000]), (ARM, SINE, BOTH, 0), *steps([6100])])
    assert late[-1][0] == CODES["ECAM_SWITCH_DONE"] and late[-1][3] == 6100
    assert late[-1][1] == cb.int32_wrap(tables[SINE].lookup(0) + tables[SINGLE].lookup(3000))


# ------------------------------------------------------------------------------ refusals

def test_every_refusal_has_its_code_in_both(driver):
    script = [
        (STEP, 5, 0, 0),  # not engaged
        (ARM, SINE, 0, 0),  # not engaged
        (ENGAGE, BROKEN, 0, 0),  # a table whose init failed
        (ENGAGE, -1, 0, 0),  # NULL
        (ENGAGE, DRRD, 0, 0),
        (CANCEL, 0, 0, 0),  # nothing armed
        (ARM, -1, 0, 0),  # NULL
        (ARM, BROKEN, 0, 0),
        (ARM, SINE, 4, 0),  # an unknown mode bit
        (ARM, SINGLE, SLAVE_RELATIVE, 0),  # master absolute into a table that does not repeat
        (ARM, SINGLE, BOTH, 3001),  # entered past its range
        (ARM, SINGLE, BOTH, 3000),  # master relative, entered at its end: accepted
        (ARM, SINE, 0, 0),  # already armed
        (CANCEL, 0, 0, 0),
        (CANCEL, 0, 0, 0),
        (INIT, 0, 0, 0),
        (STEP, 5, 0, 0),
    ]
    out = both(driver, script)
    names = ["ECAM_SWITCH_E_NOT_ENGAGED", "ECAM_SWITCH_E_NOT_ENGAGED", "ECAM_SWITCH_E_TABLE", "ECAM_SWITCH_E_NULL",
             "ECAM_SWITCH_OK", "ECAM_SWITCH_E_NO_PENDING", "ECAM_SWITCH_E_NULL", "ECAM_SWITCH_E_TABLE",
             "ECAM_SWITCH_E_MODE", "ECAM_SWITCH_E_MASTER_RANGE", "ECAM_SWITCH_E_MASTER_RANGE", "ECAM_SWITCH_OK",
             "ECAM_SWITCH_E_ARMED",
             "ECAM_SWITCH_OK", "ECAM_SWITCH_E_NO_PENDING", "ECAM_SWITCH_OK", "ECAM_SWITCH_E_NOT_ENGAGED"]  # fmt: skip
    assert [row[0] for row in out] == [CODES[n] for n in names]
    assert out[0][1:3] == (INVALID, INVALID)
    assert [row[5] for row in out[9:15]] == [0, 0, 1, 1, 0, 0]  # a refusal changes nothing


def test_a_cancelled_switch_does_not_happen(driver):
    M = driver[1][DRRD].master_counts
    out = both(driver, [(ENGAGE, DRRD, 0, 0), *steps([M - 1]), (ARM, SINE, BOTH, 0), (CANCEL, 0, 0, 0),
                        *steps([M, M + 1])])  # fmt: skip
    assert [row[0] for row in out[-2:]] == [0, 0] and out[-1][4] == 0


def test_refusals_in_python_name_field_value_and_code():
    pair = SwitchPair()
    with pytest.raises(SwitchRefused, match=r"running: None should be a table.*\(ECAM_SWITCH_E_NOT_ENGAGED\)"):
        pair.step(0)
    table = CamTable.from_bytes(table_pool()[SINGLE])
    pair.engage(table)
    with pytest.raises(SwitchRefused, match=r"master: 'absolute' should be 'relative'.*0\.\.3000") as caught:
        pair.arm(table)
    assert caught.value.status == "ECAM_SWITCH_E_MASTER_RANGE" and caught.value.code == -46
    with pytest.raises(InputError, match="master: 'sideways' should be one of"):
        mode_flags("sideways")
    with pytest.raises(InputError, match="slave_offset"):
        pair.engage(table, 0, 2**31)


# ------------------------------------------------------------------------------ property: C == Python

def _pool_sizes():
    return {k: m for k, m in zip(range(8), (36864, 65536, 36000, 36000, 3000, 7, 6, 2**20))}


@st.composite
def scripts(draw):
    """An engagement, then steps (a few counts, part of a period, or many periods, either way)
    with arms (any table, any mode, refusals included) and cancels among them, starting near a
    boundary of the engaged table."""
    sizes = _pool_sizes()
    first = draw(st.sampled_from(sorted(sizes)))
    master_offset = draw(st.one_of(st.integers(-10**6, 10**6), st.integers(-(2**62), 2**62)))
    period = sizes[first]
    master = -master_offset + period * draw(st.integers(-3, 3)) + draw(st.integers(-3, 3))
    script = [(ENGAGE, first, master_offset, draw(st.integers(-(2**31), 2**31 - 1)))]
    for _ in range(draw(st.integers(1, 40))):
        kind = draw(st.sampled_from(("step",) * 6 + ("arm", "arm", "cancel")))
        if kind == "arm":
            script.append((ARM, draw(st.integers(-1, BROKEN)), draw(st.sampled_from((0, 1, 2, 3, 3, 4))),
                           draw(st.one_of(st.just(0), st.integers(-3, 3010), st.integers(-(2**40), 2**40))),
                           draw(st.one_of(st.just(0), st.integers(-(2**31), 2**31 - 1)))))
        elif kind == "cancel":
            script.append((CANCEL, 0, 0, 0))
        else:
            size = draw(st.sampled_from((4, 4, 70_000, 300_000, 3_000_000)))
            master += draw(st.integers(-size, size))
            master = max(-(2**63), min(2**63 - 1, master))
            script.append((STEP, master, 0, 0))
    return script


@settings(max_examples=60, deadline=None, derandomize=True)
@given(script=scripts())
def test_c_and_python_agree_bit_for_bit(driver, script):
    both(driver, script)


def random_script(rng: np.random.Generator, commands: int) -> list[tuple]:
    """A seeded script of the same kind for the cross targets and the sanitizers."""
    sizes = _pool_sizes()
    script, master = [], 0
    for k in range(commands):
        if k % 200 == 0:
            first = int(rng.choice(sorted(sizes)))
            offset = int(rng.integers(-(2**40), 2**40))
            master = -offset + sizes[first] * int(rng.integers(-3, 4))
            script.append((ENGAGE, first, offset, int(rng.integers(-(2**31), 2**31))))
            continue
        r = rng.random()
        if r < 0.12:
            master_offset = int(rng.choice([0, 0, rng.integers(-3, 3010), rng.integers(-(2**40), 2**40)]))
            slave_offset = int(rng.choice([0, 0, rng.integers(-(2**31), 2**31)]))
            script.append((ARM, int(rng.integers(-1, BROKEN + 1)), int(rng.choice([0, 1, 2, 3, 3, 4])), master_offset,
                           slave_offset))  # fmt: skip
        elif r < 0.15:
            script.append((CANCEL, 0, 0, 0))
        else:
            size = int(rng.choice([4, 4, 70_000, 300_000, 3_000_000]))
            master += int(rng.integers(-size, size + 1))
            script.append((STEP, master, 0, 0))
    return script


@pytest.mark.slow
def test_sanitizers_find_nothing(tmp_path, pool):
    """The same driver with AddressSanitizer and UndefinedBehaviorSanitizer on a seeded script
    of 4000 commands (masters near int64's ends included), still equal to Python."""
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    exe = tmp_path / "switch_asan"
    flags = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O1", "-g", "-fsanitize=address,undefined",
             "-fno-sanitize-recover=all"]  # fmt: skip
    build = subprocess.run([cc, *flags, "-I", str(FIRMWARE), "-o", str(exe),
                            *(str(FIRMWARE / s) for s in DRIVER_SOURCES)], capture_output=True, text=True)  # fmt: skip
    if build.returncode != 0 and "sanitize" in build.stderr:
        pytest.skip(f"sanitizers unavailable: {build.stderr.splitlines()[0]}")
    assert build.returncode == 0, build.stderr
    write_pool(tmp_path, pool[0])
    script = random_script(np.random.default_rng(2303), 4000)
    script += [(ENGAGE, KNIFE, -(2**63) + 10, 0), *steps([2**63 - 5, -(2**63), 2**63 - 1]),
               (ARM, DRRD, BOTH, 0), *steps([-(2**63) + 3, 2**63 - 1, 0])]  # fmt: skip
    assert run_c(exe, tmp_path, script) == run_python(script, pool[1])


def test_firmware_emit_writes_the_switch_and_it_builds_from_there(tmp_path, capsys):
    """`ecam firmware --emit DIR` ships ecam_table_pair.c/.h beside the runtime, byte for byte,
    and the emitted pair compiles on its own with the runtime's strict warnings."""
    from argparse import Namespace

    from ecam.app.firmware_command import cmd_firmware

    assert cmd_firmware(Namespace(emit=str(tmp_path))) == 0
    printed = capsys.readouterr().out
    for name in ("ecam_table_pair.c", "ecam_table_pair.h", "ecam_table.h"):
        assert (tmp_path / name).read_bytes() == (FIRMWARE / name).read_bytes()
        assert f"wrote {tmp_path / name}" in printed
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang) on PATH")
    build = subprocess.run([cc, *STRICT, "-c", "-o", str(tmp_path / "pair.o"), str(tmp_path / "ecam_table_pair.c")],
                           capture_output=True, text=True)  # fmt: skip
    assert build.returncode == 0 and build.stderr == "", build.stderr


@pytest.mark.parametrize("running,pending", [(DRRD, SINE), (KNIFE, KNIFE_Q), (SINE, TINY), (SINGLE, SINE)])
def test_the_virtual_drive_queued_switch_is_the_firmware_switch_both_ways(pool, running, pending):
    """The rig's drive-side cam slot (hil_sim/drive/cam_slot.py: 0x2001:01 = 3 queues the pending
    table, 0x2001:05 its PLCopen placement) commands, cycle by cycle, the positions SwitchPair
    (and so ecam_table_pair.c) computes, in every mode, for a master that moves forwards across
    a switch and then backwards across another (armed on the way back, to the first table where
    it repeats), with jumps of up to a seventh of a period (int32 targets compared modulo 2^32,
    as the drive's position rolls over). The table that does not repeat (SINGLE) has ended when
    the switch is armed: the pending table takes over at the next cycle's master."""
    from hil_sim.drive.cam_slot import (CAM_COMMAND_ACTIVATE, CAM_COMMAND_ACTIVATE_AT_PERIOD_END, CAM_MODE_DRIVE_SIDE,
                                        CamSlot)
    from hil_sim.drive.objects import CAM_MODE, CAM_STATUS, CAM_SWITCH_MODE, MASTER_POSITION
    from hil_sim.int32 import wrap_int32

    blobs, tables = pool
    rng = np.random.default_rng(running * 10 + pending)
    back = running if tables[running].periodic else pending
    steps = np.concatenate([rng.integers(0, tables[running].master_counts // 7 + 2, 60),
                            -rng.integers(0, tables[back].master_counts // 7 + 2, 60)])  # forwards, backwards
    masters = np.cumsum(steps).tolist()
    for mode in range(4):
        slot = CamSlot({CAM_STATUS: 0, CAM_MODE: 0, CAM_SWITCH_MODE: mode})
        slot.verify_download(blobs[running])
        slot.write_command(CAM_COMMAND_ACTIVATE)
        slot.write_mode(CAM_MODE_DRIVE_SIDE)
        pair = SwitchPair()
        pair.engage(tables[running])
        switched = []
        for k, master in enumerate(masters):
            for at, table in ((20, pending), (70, back)):
                if k == at:
                    slot.verify_download(blobs[table])
                    slot.write_command(CAM_COMMAND_ACTIVATE_AT_PERIOD_END)
                    pair.arm_mode(tables[table], mode)
            slot.values[MASTER_POSITION] = wrap_int32(master)
            target, _ = slot.target(0.001)
            sample = pair.step(master)
            assert wrap_int32(target) == sample.position, (mode, k, master)
            if sample.switched:
                switched.append(k)
        assert pair.switches == 2 and 20 <= switched[0] < 60 <= 70 <= switched[1], switched
        assert masters[switched[1]] < masters[switched[1] - 1]  # the second one going backwards
