"""Hostile values in cam and scene files, through the released commands (issue 14).

Valid files are mutated at random (seeded, bounded: hypothesis with the suite's derandomized
profile): a value of the wrong type, a huge, tiny, negative, NaN or infinite number, an integer
past int64, an empty table, unicode and very long strings, huge arrays, a field deleted or an
unknown one added. Each file goes through ``ecam check``, ``compile`` and ``export`` (scenes
through ``ecam sim``) in this process, by :func:`ecam.app.cli.main`. Every outcome must be a
run (exit 0 or 1) or one line on stderr with exit 2, at once: never an exception out of
``main``, a traceback, a warning on stderr (numpy's RuntimeWarning is a second line and the
sign of a non-finite number) or an unbounded message.
"""

import contextlib
import copy
import csv
import datetime
import io
import math
import re
import tomllib
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings, strategies as st

from ecam.app.cli import main
from ecam.export import EXPORTERS as TABLE_FORMATS

ROOT = Path(__file__).resolve().parent.parent
CAMS = ROOT / "firmware_tables" / "cams"
SCENES = ROOT / "hil_sim" / "scenes"
VENDOR_FORMATS = ("codesys", "twincat-cnc", "kollmorgen", "elmo", "technosoft", "csv")
# The longest stderr line allowed: a message shows a value cut to 60 characters (ecam.validate.show),
# so a 100 000-character value must not come back whole.
MAX_LINE = 600

# --- TOML writer (tomllib only reads) ---------------------------------------------------------
_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def toml_string(text: str) -> str:
    out = []
    for char in text:
        if char in _ESCAPES:
            out.append(_ESCAPES[char])
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            out.append(f"\\u{ord(char):04X}")
        else:
            out.append(char)
    return '"' + "".join(out) + '"'


def toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)  # nan, inf, -inf, 1e+300 and integers of any size are TOML here
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, (datetime.datetime, datetime.date)):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_string(k)} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(type(value))


def to_toml(document: dict) -> str:
    """One ``key = value`` line per top-level key; tables inline (tomllib reads the same mapping)."""
    return "".join(f"{toml_string(key)} = {toml_value(value)}\n" for key, value in document.items())


def test_the_writer_round_trips():
    document = {"a": [1, 2.5, math.inf, "x\x00\"y\u202e"], "t": {"s": [{"k": True}], "d": datetime.date(2024, 1, 2)},
                "big": 10**30, "e": {}}
    text = to_toml(document)
    assert tomllib.loads(text) == document


# --- hostile values -----------------------------------------------------------------------------
HOSTILE = [0.0, -0.0, -1.0, 5e-324, 1e-300, 1e-9, 1e150, 1.5e150, 1e300, 1.7976931348623157e308, -1e308, math.inf,
           -math.inf, math.nan, 0, -1, 1, 2, 2**31, 2**31 + 1, 2**53 + 1, 2**63, 2**64, -(2**63) - 1, 10**30, 10**400,
           "", "x" * 100_000, "match", "dwell", "poly5", "2 counts", "nan counts", "-1 counts", "1e-300 counts",
           "auto", "quintic", "é\u202e\U0001F600", "\x00", "/dev/zero", "../../etc/passwd", True, False, [], {},
           # issue 28: markup and comment syntax of the outputs, control characters, line separators
           "$$", "$x^$", "\\alpha", "*)\nVAR_GLOBAL injected : INT := 1; END_VAR\n(* x\n1,2\n3,4", "*) (* /* // #",
           "a,b\"c", "a\u2028b", "\x1b[31m", "a\tb", "<x>&amp;",
           [1, "a"], list(range(10_000)), [[[[]]]], {"a": {"b": []}}, datetime.date(1970, 1, 1),
           datetime.datetime(2000, 1, 1, 12, 30)]

values = st.one_of(
    st.sampled_from(HOSTILE),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.text(max_size=12),
)


def paths(node, prefix=()):
    """Every place in a parsed document: (path, value), tables and arrays included."""
    out = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        out.append((prefix + (key,), value))
        out.extend(paths(value, prefix + (key,)))
    return out


def mutate(document: dict, data) -> dict:
    """1..3 hostile changes: a value replaced, a field deleted, an unknown field added, a table
    or array emptied."""
    document = copy.deepcopy(document)
    for _ in range(data.draw(st.integers(1, 3), label="changes")):
        places = paths(document)
        path, old = places[data.draw(st.integers(0, len(places) - 1), label="where")]
        *parents, key = path
        parent = document
        for step in parents:
            parent = parent[step]
        action = data.draw(st.sampled_from(["replace", "replace", "replace", "delete", "add", "empty"]), label="how")
        if action == "replace":
            parent[key] = data.draw(values, label="value")
        elif action == "delete" and isinstance(parent, dict):
            del parent[key]
        elif action == "add" and isinstance(old, dict):
            old[data.draw(st.sampled_from(["unknown", "", "é", "a\nb", "x" * 300]), label="key")] = data.draw(values)
        elif action == "empty":
            parent[key] = {} if isinstance(old, dict) else []
    return document


# --- running the commands -------------------------------------------------------------------
def run(args) -> tuple[int, str, str, list]:
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        status = main([str(a) for a in args])
    return status, out.getvalue(), err.getvalue(), [w for w in caught if issubclass(w.category, RuntimeWarning)]


def assert_clean(args, text):
    status, out, err, runtime_warnings = run(args)
    where = f"ecam {' '.join(map(str, args))} on\n{text[:2000]}"
    assert not runtime_warnings, f"{where}\n{runtime_warnings[0]}"
    assert status in (0, 1, 2), where
    if status == 2:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("ecam: error: "), f"{where}\n{err[:3000]}"
        assert len(lines[0]) <= MAX_LINE, f"{where}\n{lines[0][:3000]}"
    else:
        assert err == "" and out, f"{where}\n{err[:3000]}"
    return status


def small_table(document: dict) -> dict:
    """The cam with a small fixed table, so that a mutant that stays valid compiles in a blink."""
    document = dict(document)
    document["table"] = {"interp": "cubic", "points": 37, "master_counts": 3600,
                         "slave_counts_per_unit": document.get("table", {}).get("slave_counts_per_unit", 1000.0)}
    return document


CAM_BASES = [small_table(tomllib.loads(path.read_text())) for path in sorted(CAMS.glob("*.toml"))]
CAM_BASES.append(small_table(tomllib.loads(
    'name = "polynomials"\nmaster_period = 1.0\nmaster_unit = "rev"\nslave_unit = "rad"\n'
    '[[segment]]\nlaw = "dwell"\nspan = 0.25\n'
    '[[segment]]\nlaw = "poly7"\nspan = 0.25\nstroke = 3.0\nstart_velocity = "match"\nend_velocity = 2.0\n'
    '[[segment]]\nlaw = "constant_velocity"\nspan = 0.25\nstroke = 0.5\n'
    '[[segment]]\nlaw = "poly5"\nspan = 0.25\nto = 0.0\nstart_velocity = "match"\nend_acceleration = 0.0\n')))

# Command-line values: wrong, extreme, and a few valid ones (never a valid pair that asks for a
# table of millions of points: that is a legitimate minute of work, not a hostile input).
OPTION_VALUES = {
    "--points": ["-1", "0", "1", "2", "37", "4194306", "1e3", "nan", "", "9" * 40],
    "--master-counts": ["-1", "0", "1", "2", "3600", "2147483649", "1e3", "nan", "9" * 40],
    "--tolerance": ["0", "-1", "nan", "inf", "1e-300", "1e300", "2 counts", "1 furlong", "", "x" * 1000],
    "--slave-counts-per-unit": ["0", "-1", "nan", "inf", "5e-324", "1e-6", "1e12", "1e13", "1e308"],
    "--interp": ["linear", "cubic", "quintic", "auto", "spline", ""],
    "--format": ["c", "bin,csv,json", "", ",,", "C", "c,c", "x" * 1000, "a\nb"],
}


@st.composite
def options(draw, command):
    chosen = []
    names = ["--points", "--master-counts", "--slave-counts-per-unit", "--interp"]
    names.append("--tolerance" if command == "export" else "--format")
    for name in draw(st.lists(st.sampled_from(names), max_size=2, unique=True)):
        chosen += [name, draw(st.sampled_from(OPTION_VALUES[name]))]
    return chosen


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


# No shrinking: a failure is shown as found, at once (shrinking re-runs commands for minutes).
FUZZ = {"suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large],
        "phases": [Phase.explicit, Phase.generate]}


@settings(max_examples=40, **FUZZ)
@given(st.data())
def test_hostile_cam_files_get_one_line(workdir, data):
    document = mutate(data.draw(st.sampled_from(CAM_BASES), label="cam"), data)
    text = to_toml(document)
    path = workdir / "cam.toml"
    path.write_text(text, encoding="utf-8")
    status = assert_clean(["check", path], text)
    if status == 2 and data.draw(st.booleans(), label="only check"):
        return  # a file check refuses, compile and export refuse too; every other time, see that they do
    assert_clean(["compile", path, "-o", workdir / "out", "--format", ",".join(sorted(TABLE_FORMATS)),
                  *data.draw(options("compile"), label="options")], text)
    assert_clean(["export", path, "--to", data.draw(st.sampled_from(VENDOR_FORMATS), label="to"), "-o",
                  workdir / "export.txt", *data.draw(options("export"), label="options")], text)


@pytest.mark.slow
def test_hostile_command_line_values_get_one_line(workdir):
    """Every option value above on a valid cam (one at a time)."""
    cam = workdir / "small.toml"
    cam.write_text(to_toml(CAM_BASES[1]), encoding="utf-8")
    for name, choices in OPTION_VALUES.items():
        for value in choices:
            if name != "--tolerance":
                assert_clean(["compile", cam, "-o", workdir / "out", name, value], f"{name} {value}")
            if name != "--format":
                assert_clean(["export", cam, "--to", "csv", "-o", workdir / "e.csv", name, value], f"{name} {value}")
    for speed in ("0", "-1", "nan", "inf", "1e308", "5e-324", "1e300 rpm", "60 furlongs/s", "", "x" * 1000):
        assert_clean(["check", cam, "--speed", speed], speed)


# --- scene files through `ecam sim` -------------------------------------------------------------
# A valid mutant runs the rig, so the runs are kept short: every base scene runs a few cycles, and
# the rig's cycle limit is lowered for the test, so that a mutant asking for a long run (a tiny
# cycle time, a slow master, a long duration) is refused at once, as a longer one than
# hil_sim.scene.MAX_CYCLES is (the refusal is itself a hostile-input path).
FUZZ_MAX_CYCLES = 120


def scene_base(path: Path) -> dict:
    document = tomllib.loads(path.read_text())
    document["cam"]["file"] = str((path.parent / document["cam"]["file"]).resolve())
    for event in document.get("event", []):  # a switch's cam, as the scene's (hil_sim.events)
        if "cam" in event:
            event["cam"] = str((path.parent / event["cam"]).resolve())
    if "points" in document["cam"]:
        document["cam"]["points"] = 37
        document["cam"]["master_counts"] = 36 * 128
    document["duration"] = {"cycles": 60}
    return document


SCENE_BASES = [scene_base(path) for path in sorted(SCENES.glob("*.toml"))]


@pytest.mark.slow
@settings(max_examples=25, **FUZZ)
@given(st.data())
def test_hostile_scene_files_get_one_line(workdir, data):
    import hil_sim.rig.plan
    import hil_sim.scene

    document = mutate(data.draw(st.sampled_from(SCENE_BASES), label="scene"), data)
    text = to_toml(document)
    path = workdir / "scene.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(hil_sim.scene, "MAX_CYCLES", FUZZ_MAX_CYCLES)
        patch.setattr(hil_sim.rig.plan, "MAX_CYCLES", FUZZ_MAX_CYCLES)
        assert_clean(["sim", path, "--json"], text)


# The scene defects this fuzz found, each as it was found (one line and exit 2, naming the field).
FOUND = [
    ("soft_coupling", ("cam", "file"), "a\x00b", "cam.file: 'a\\x00b' cannot be resolved"),
    ("soft_coupling", ("cam", "file"), "x" * 5000, "cannot be resolved: [Errno 36]"),
    ("soft_coupling", ("cam", "file"), "/dev/zero", "cam.file: '/dev/zero' should be a regular file"),
    ("rotary_knife", ("limits", "tracking_window", 1), 10**400, "limits.tracking_window[1]: 1e+400"),
    ("rotary_knife", ("limits", "tracking_window", 1), 1.7976931348623157e308, "should be <= 1e+12"),
    ("soft_coupling", ("mechanics", "gear_ratio"), 1e-300, "mechanics.gear_ratio: 1e-300 should be >= 0.0001"),
    ("soft_coupling", ("mechanics", "load_inertia"), 5e-324, "mechanics.load_inertia: 4.94065645841e-324 should be 0 or >="),
    ("soft_coupling", ("mechanics", "motor_inertia"), 5e-324, "mechanics.motor_inertia: 4.94065645841e-324 should be >="),
    ("rotary_knife", ("mechanics", "slave_units_per_load_radian"), 5e-324, "mechanics.slave_units_per_load_radian"),
    ("rotary_knife", ("master", "max_acceleration"), 5e-324, "master.profile 'start_stop': no ramp to 720 deg/s"),
    ("cam_in", ("master", "slave_start"), -151999.0, "master.profile 'cam_in': no cam-in"),
    ("cam_in", ("master", "speed_rpm"), 5e-324, "master.speed_rpm: 4.94065645841e-324 should be non-zero"),
]


@pytest.mark.parametrize("name, path, value, expected", FOUND, ids=lambda v: str(v)[:30])
def test_scene_defects_the_fuzz_found_are_one_line(workdir, name, path, value, expected):
    document = copy.deepcopy(next(b for b in SCENE_BASES if b["name"] == name))
    node = document
    for step in path[:-1]:
        node = node[step]
    node[path[-1]] = value
    scene = workdir / "found.toml"
    scene.write_text(to_toml(document))
    status, out, err, runtime_warnings = run(["sim", scene, "--json"])
    assert status == 2 and len(err.splitlines()) == 1 and not runtime_warnings, err
    assert expected in err, err


# --- names and units: control characters and the outputs' markup (issue 28) ---------------------
# Text a name or a unit may hold, and text that breaks one of the places they go: a comment of
# IEC 61131-3 source, a CSV header, an ISG table's '#' comment, matplotlib's mathtext, XML, a
# terminal line.
TEXTS = st.one_of(
    st.sampled_from(["$$", "$x^$", "\\alpha$", "*)", "(*", "/*", "*/", "//", "#", ",", '"', "a,b\"c",
                     "*) VAR_GLOBAL injected : INT := 1; END_VAR (*", "\x00", "\n", "\r\n", "\x1b[2J",
                     "\u2028", "\u0085", "\u202e", "\t", "<![CDATA[", "&", "é\U0001F600", "x" * 300]),
    st.text(max_size=12),
)


def iec_code(text: str) -> str:
    from test_hostile_inputs import iec_code as strip

    return strip(text)


def assert_export_intact(to: str, text: str) -> None:
    """The export's structure is the one it writes for any cam: the user's text stayed inside
    the places meant for it."""
    if to == "codesys":
        code = iec_code(text)
        assert code.count("VAR_GLOBAL") == 1 and code.count("END_VAR") == 1 and ":=" in code, code[:500]
        assert re.fullmatch(r"\s*VAR_GLOBAL\s+\w+ : ARRAY\[0\.\.\d+\] OF SMC_CAMXYVA := \[.*\];\s*\w+ : MC_CAM_REF := "
                            r"\(.*\);\s*END_VAR\s*", code, flags=re.S), code[:500]
    elif to == "csv":
        rows = list(csv.reader(line for line in text.splitlines() if not line.startswith("#")))
        assert len({len(row) for row in rows}) == 1, rows[:3]
    elif to == "twincat-cnc":
        keys = [line.split("#")[0].split("=")[0].strip() for line in text.splitlines() if "=" in line.split("#")[0]]
        assert keys == ["Tablename", "Table-ID", "Tabletype", "Functiontype", "Lines"], keys


@settings(max_examples=30, **FUZZ)
@given(st.data())
def test_hostile_names_and_units(workdir, data):
    """The polynomial cam with drawn names and units through check, compile (every format),
    every vendor export and plot: one line, or outputs whose structure holds."""
    document = copy.deepcopy(CAM_BASES[-1])
    document["table"]["tolerance"] = 0.001
    for key in ("name", "master_unit", "slave_unit"):
        if data.draw(st.booleans(), label=f"set {key}"):
            document[key] = data.draw(TEXTS, label=key)
    for segment in document["segment"]:
        if data.draw(st.booleans(), label="segment name"):
            segment["name"] = data.draw(TEXTS, label="segment name")
    if data.draw(st.booleans(), label="tappet"):  # a switch track's name goes into the CODESYS header
        document["tappet"] = [{"name": data.draw(TEXTS, label="tappet name"), "on": 0.1, "off": 0.4}]
    text = to_toml(document)
    path = workdir / "names.toml"
    path.write_text(text, encoding="utf-8")
    if assert_clean(["check", path], text) == 2:
        return
    out = workdir / "names_out"
    assert_clean(["compile", path, "-o", out, "--format", ",".join(sorted(TABLE_FORMATS))], text)
    for to in VENDOR_FORMATS:
        target = workdir / f"names.{to}.txt"
        target.unlink(missing_ok=True)
        if assert_clean(["export", path, "--to", to, "-o", target], text) == 0:
            assert_export_intact(to, target.read_text(encoding="utf-8"))
    if data.draw(st.booleans(), label="plot"):
        assert_clean(["plot", path, "-o", workdir / "names.svg"], text)


# --- device and input paths as outputs (issue 28) -----------------------------------------------
def output_targets(base: Path, cam: Path) -> dict:
    """Paths an output may be pointed at, each made afresh: what must survive, what may be written."""
    import os
    import shutil

    if base.exists():
        shutil.rmtree(base)
    base.mkdir()
    os.mkfifo(base / "fifo")
    (base / "precious.txt").write_text("precious")
    (base / "to_fifo.svg").symlink_to(base / "fifo")
    (base / "to_stream.svg").symlink_to("/proc/self/fd/1")
    (base / "to_precious.svg").symlink_to(base / "precious.txt")
    (base / "dangling.svg").symlink_to(base / "nowhere")
    (base / "loop_a.svg").symlink_to(base / "loop_b.svg")
    (base / "loop_b.svg").symlink_to(base / "loop_a.svg")
    os.link(cam, base / "hard_link_to_cam.svg")
    (base / "dir.svg").mkdir()
    return {
        "new": base / "new.svg", "cam": cam, "cam relative": Path(os.path.relpath(cam)),
        "cam through ..": cam.parent / ".." / cam.parent.name / cam.name, "hard link": base / "hard_link_to_cam.svg",
        "fifo": base / "fifo", "link to fifo": base / "to_fifo.svg", "link to stream": base / "to_stream.svg",
        "link to file": base / "to_precious.svg", "dangling link": base / "dangling.svg",
        "loop": base / "loop_a.svg", "directory": base / "dir.svg", "long": base / ("x" * 300 + ".svg"),
        "under a file": base / "precious.txt" / "x.svg",
    }


@settings(max_examples=40, **FUZZ)
@given(st.data())
def test_hostile_output_paths_never_destroy(workdir, data):
    """An output pointed at a device, a FIFO, a link to a stream, a loop, a directory, an overlong
    name or the input itself: one line, and every one of them as it was; a new path, a dangling
    link or a link to a regular file is written (the link replaced, its target untouched)."""
    import os
    import stat as stat_module

    cam = workdir / "out_cam.toml"
    cam.write_text(to_toml(CAM_BASES[-1] | {"name": "out_cam"}), encoding="utf-8")
    before = cam.read_bytes()
    targets = output_targets(workdir / "targets", cam)
    which = data.draw(st.sampled_from(sorted(targets)), label="target")
    target = targets[which]
    command = data.draw(st.sampled_from(["export", "plot"]), label="command")
    if command == "export":
        args = ["export", cam, "--to", "csv", "--tolerance", "0.001", "-o", target]
    else:
        args = ["plot", cam, "-o", target]
    status = assert_clean(args, f"{command} -o {which}")
    assert cam.read_bytes() == before, which
    base = workdir / "targets"
    assert stat_module.S_ISFIFO(os.lstat(base / "fifo").st_mode)
    assert os.readlink(base / "to_stream.svg") == "/proc/self/fd/1"
    assert (base / "precious.txt").read_text() == "precious"
    assert (base / "dir.svg").is_dir()
    if which in ("cam", "cam relative", "cam through ..", "hard link", "fifo", "link to fifo", "link to stream",
                 "loop", "directory", "long", "under a file"):
        assert status == 2, which
