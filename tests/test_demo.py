"""`ecam demo`, the README's first command: every file it promises, tables that load, the stiff
scene passing and the soft one failing (the point of the demo), and an HTML page of both."""

import re
import subprocess
import sys

import pytest

from ecam import CamTable

SEED_CAMS = ("combination_drrd", "modified_sine")

# the whole demo runs once for the module (about 3 s): out of the quick subset
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    run = subprocess.run([sys.executable, "-m", "ecam.app", "demo", "-o", str(out)],
                         capture_output=True, text=True, timeout=300)
    return out, run


def test_the_demo_exits_cleanly_and_writes_every_file(demo):
    out, run = demo
    assert run.returncode == 0, run.stderr
    expected = {f"{stem}{suffix}" for stem in SEED_CAMS for suffix in (".png", ".h", ".bin")}
    expected |= {"sim_stiff_coupling.png", "sim_soft_coupling.png", "report.html"}
    assert expected <= {p.name for p in out.iterdir()}
    assert all((out / name).stat().st_size > 0 for name in expected)


def test_the_demo_tables_load_and_match_their_printed_certificates(demo):
    out, run = demo
    for stem in SEED_CAMS:
        table = CamTable.from_bytes((out / f"{stem}.bin").read_bytes())
        printed = re.search(rf"{stem}: \w+ table, (\d+) points, .* CRC-32 0x([0-9a-f]{{8}})", run.stdout)
        assert printed, run.stdout
        assert table.points == int(printed.group(1)) and table.crc32 == int(printed.group(2), 16)
        assert f"0x{table.crc32:08x}" in (out / f"{stem}.h").read_text()


def test_the_stiff_coupling_passes_and_the_soft_one_fails(demo):
    _, run = demo
    assert re.search(r"scene stiff_coupling: PASSED", run.stdout), run.stdout
    assert re.search(r"scene soft_coupling: FAILED .*\(.+ failed\)", run.stdout), run.stdout


def test_the_demo_page_shows_both_scenes_and_fetches_nothing(demo):
    out, run = demo
    # The last line tells the user where the page is.
    assert run.stdout.rstrip().splitlines()[-1] == (
        f"ecam demo: open {out / 'report.html'} in a browser for the verdicts, checks, plots "
        "and scenes")
    page = (out / "report.html").read_text()
    assert "stiff_coupling" in page and "soft_coupling" in page
    assert "1 of 2" in page
    assert not re.search(r"""(src|href)=["']https?://""", page)


def test_the_report_carries_the_motor_torque_the_page_plots():
    import numpy as np

    from hil_sim import SCENES_DIR, load_scene, run_scene

    report = run_scene(load_scene(SCENES_DIR / "stiff_coupling.toml"))
    torque = report.series["peak_motor_torque"]
    assert len(torque) == len(report.series["time_s"]) == report.cycles
    assert float(np.max(torque)) == report.summary["mechanics"]["peak_motor_torque"]
    assert float(np.max(torque)) <= report.summary["mechanics"]["motor_torque_limit"]


def test_the_demo_says_its_failing_scene_fails_on_purpose(demo):
    out, run = demo
    assert "-- soft_coupling: a soft coupling at 150 rpm: this scene FAILS ON PURPOSE" in run.stdout
    assert ("ecam demo: done (stiff_coupling passed, soft_coupling failed, as intended: the soft coupling "
            "fails on purpose)") in run.stdout
