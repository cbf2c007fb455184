"""Robustness sweeps: the [sweep] table (hil_sim.sweep_spec), `ecam sweep` on Dask
(ecam.app.sweep), the yield assertion of the pytest plugin."""

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import hil_sim
from ecam.app.pytest_plugin import assert_yield
from ecam.errors import CamFileError
from hil_sim.scene import load_scene, parse_scene
from hil_sim.sweep_spec import nominal_value, parse_sweep, sample_data

ROOT = Path(__file__).resolve().parents[1]
STIFF = hil_sim.SCENES_DIR / "stiff_coupling.toml"

# The shipped stiff_coupling scene, one master period long, with its spread: the coupling within
# +-15 % (one sigma) of its catalogue stiffness, a gearhead backlash from none to 5 arcmin (the
# scene says 3 arcmin quadruples the coupling torque), the load within -10 / +30 %.
SWEEP = """
[sweep]
samples = 6
seed = 3
speeds_rpm = [60.0, 240.0]
[sweep.vary]
"mechanics.coupling_stiffness" = { distribution = "normal", mean = 1.0, std = 0.15, relative = true, minimum = 0.5 }
"mechanics.gear_backlash" = { distribution = "uniform", low = 0.0, high = 0.0015 }
"mechanics.load_inertia" = { distribution = "triangular", low = 0.9, mode = 1.0, high = 1.3, relative = true }
"""


def _scene_text(sweep: str = SWEEP) -> str:
    text = STIFF.read_text().replace("master_periods = 2.0", "master_periods = 1.0")
    assert "master_periods = 1.0" in text
    return text + sweep


@pytest.fixture
def scene_file(tmp_path) -> Path:
    path = tmp_path / "stiff_sweep.toml"
    path.write_text(_scene_text())
    return path


def _data(sweep: str) -> dict:
    return tomllib.loads(_scene_text(sweep))


def test_a_scene_run_ignores_its_sweep_table(scene_file):
    plain = load_scene(STIFF)
    with_sweep = load_scene(scene_file)
    assert with_sweep.mechanics == plain.mechanics and with_sweep.limits == plain.limits


def test_the_sweep_table_reads_with_its_defaults():
    spec = parse_sweep(_data(SWEEP), base=hil_sim.SCENES_DIR)
    assert spec.samples == 6 and spec.seed == 3 and spec.method == "latin_hypercube"
    assert spec.speeds_rpm == (60.0, 240.0) and spec.speeds is None
    assert spec.tuning == "per_sample" and spec.fidelity == "full" and spec.required_yield == 0.95
    assert [name for name, _ in spec.vary] == ["mechanics.coupling_stiffness",
                                               "mechanics.gear_backlash", "mechanics.load_inertia"]
    stiffness = spec.distributions["mechanics.coupling_stiffness"]
    assert stiffness.relative and stiffness.std == 0.15 and stiffness.minimum == 0.5


@pytest.mark.parametrize("sweep, message", [
    ("[sweep]\nsamples = 4\n", r"sweep.vary: missing; expected a table"),
    ("[sweep]\nsample = 4\n[sweep.vary]\n", r"sweep.sample: unknown field; expected one of"),
    ("[sweep]\nsamples = 0\n[sweep.vary]\n'mechanics.load_inertia' = { distribution = 'uniform', low = 0.01, high = 0.03 }\n",
     r"sweep.samples: 0 should be an integer in 1..1000000"),
    ("[sweep]\nmethod = 'random'\n[sweep.vary]\n'mechanics.load_inertia' = { distribution = 'uniform', low = 0.01, high = 0.03 }\n",
     r"sweep.method: 'random' should be one of latin_hypercube, monte_carlo, grid, sobol"),
    ("[sweep.vary]\n'mechanics.load_inertia' = { distribution = 'normal', mean = 1.0, std = -0.1, relative = true }\n",
     r'sweep.vary."mechanics.load_inertia".std: -0.1 should be > 0'),
    ("[sweep.vary]\n'mechanics.load_inertia' = { distribution = 'uniform', low = 0.01, hi = 0.03 }\n",
     r'sweep.vary."mechanics.load_inertia".hi: unknown field; expected one of'),
    ("[sweep.vary]\n'mechanics.coupling_stifness' = { distribution = 'uniform', low = 1e6, high = 3e6 }\n",
     r'sweep.vary."mechanics.coupling_stifness": the scene with its median 2e\+06 does not read: '
     r"mechanics.coupling_stifness: unknown field"),
    ("[sweep.vary]\n'mechanics.motor_damping' = { distribution = 'uniform', low = 0.5, high = 1.5, relative = true }\n"
     "'mechanics.coupling_inertia' = { distribution = 'normal', mean = 1.0, std = 0.1, relative = true }\n",
     r'sweep.vary."mechanics.coupling_inertia": relative, but the scene does not give '
     r"mechanics.coupling_inertia"),
    ("[sweep.vary]\n'cam.file' = { distribution = 'uniform', low = 0.5, high = 1.5 }\n",
     r"sweep.vary.\"cam.file\": cam.file: '.*' is not a number in the scene"),
    ("[sweep.vary]\n'mechanics.gear_ratio' = { distribution = 'uniform', low = -2.0, high = -1.0 }\n",
     r'sweep.vary."mechanics.gear_ratio": the scene with its median -1.5 does not read: '
     r"mechanics.gear_ratio: -1.5 should be >= 0.0001"),
    ("[sweep]\nspeeds = [360.0, 0.0]\n[sweep.vary]\n'mechanics.load_inertia' = { distribution = 'uniform', low = 0.01, high = 0.03 }\n",
     r"sweep.speeds: 0 should be a speed of magnitude in"),
    ("[sweep]\nmethod = 'grid'\n[sweep.vary]\n'mechanics.load_inertia' = { distribution = 'uniform', low = 0.01, high = 0.03 }\n"
     "'mechanics.motor_inertia' = { distribution = 'uniform', low = 1e-4, high = 2e-4 }\n"
     "'mechanics.gear_efficiency' = { distribution = 'uniform', low = 0.9, high = 0.97 }\n",
     r"sweep.method: 'grid' should vary one or two fields, not 3"),
])
def test_bad_sweep_tables_are_one_line_naming_the_field(sweep, message):
    with pytest.raises(CamFileError, match=message) as caught:
        parse_sweep(_data(sweep), base=hil_sim.SCENES_DIR, source="x.toml")
    assert "\n" not in str(caught.value) and str(caught.value).startswith("scene x.toml: ")


def test_a_sample_is_the_scene_with_its_fields_replaced_and_validated_again():
    data = _data(SWEEP)
    values = {"mechanics.coupling_stiffness": 1.7e6, "drive.gains.velocity_bandwidth_hz": 150.0,
              "drive.substeps": 7.6}
    sample = sample_data(data, values)
    assert "sweep" not in sample and data["mechanics"]["coupling_stiffness"] == 2.0e6  # a copy
    scene = parse_scene(sample, base=hil_sim.SCENES_DIR)
    assert dict(scene.mechanics.values)["coupling_stiffness"] == 1.7e6
    assert dict(scene.drive.gains)["velocity_bandwidth_hz"] == 150.0
    assert scene.drive.substeps == 8  # the scene's value is an integer: rounded
    with pytest.raises(CamFileError, match="mechanics.coupling_stiffness: -1 should be >= 1e-06"):
        parse_scene(sample_data(data, {"mechanics.coupling_stiffness": -1.0}), base=hil_sim.SCENES_DIR)
    # arrays of tables by index
    machine = {"axis": [{"mechanics": {"load_inertia": 1.0}}, {"mechanics": {"load_inertia": 2.0}}]}
    assert nominal_value(machine, "axis[1].mechanics.load_inertia") == 2.0
    assert sample_data(machine, {"axis[1].mechanics.load_inertia": 3.0})["axis"][1]["mechanics"] == {"load_inertia": 3.0}


def test_without_dask_the_command_says_what_to_install(scene_file):
    code = ("import sys; sys.modules['dask'] = None; sys.modules['distributed'] = None; "
            "from ecam.app.cli import main; sys.exit(main(sys.argv[1:]))")
    done = subprocess.run([sys.executable, "-c", code, "sweep", str(scene_file)],
                          capture_output=True, text=True, cwd=scene_file.parent)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == "ecam: error: ecam sweep needs dask.distributed: pip install 'ecam[sweep]'\n"


def test_importing_ecam_and_hil_sim_and_reading_a_sweep_loads_no_dask():
    code = ("import sys, ecam, hil_sim, ecam.sampling, ecam.statistics, hil_sim.sweep_spec, "
            "ecam.app.sweep_command, ecam.app.sweep_sample; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed', 'SALib')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _sweep(scene_file, out, *extra):
    done = subprocess.run([sys.executable, "-m", "ecam.app", "sweep", str(scene_file), "-o", str(out),
                           "--json", *extra], capture_output=True, text=True, cwd=scene_file.parent)
    assert done.returncode in (0, 1), done.stderr
    return json.loads(done.stdout), done


@pytest.mark.slow
def test_a_sweep_gives_the_same_summary_on_one_and_two_workers_and_resumes(scene_file, tmp_path):
    one, _ = _sweep(scene_file, tmp_path / "one", "--workers", "1", "--html", str(tmp_path / "one.html"))
    two, done = _sweep(scene_file, tmp_path / "two", "--workers", "2", "--html", str(tmp_path / "two.html"))
    assert one == two
    page = (tmp_path / "one.html").read_text()
    assert page == (tmp_path / "two.html").read_text()
    # a histogram per check with a limit and a value, a scatter plot per varied field
    histograms = [c for c in one["checks"] if isinstance(c["limit"], (int, float)) and c["max"] is not None]
    assert len(histograms) >= 8 and page.count("<svg") == len(histograms) + 3
    assert "coupling_peak_torque [N m]" in page and "mechanics.gear_backlash</code>" in page
    assert "Traceback" not in done.stderr
    assert done.returncode == 1  # far from 95 %: 3 arcmin of backlash hammers this coupling
    assert one["samples"] == 6 and one["speeds"] == [360.0, 1440.0] and one["unit"] == "deg"
    assert 0.0 <= one["yield_interval"][0] <= one["yield"] <= one["yield_interval"][1] <= 1.0
    peak = next(c for c in one["checks"] if c["name"] == "coupling_peak_torque")
    assert peak["failures"] > 0 and peak["worst"]["value"] > peak["limit"]
    # the ranking is Spearman's rho of each field with each sample's largest value / limit,
    # largest magnitude first (scipy's spearmanr over the results file is the oracle)
    from scipy import stats

    sensitivity = one["sensitivity"]
    assert sensitivity["method"] == "spearman"
    rows = [json.loads(line) for line in (tmp_path / "one" / "results.jsonl").read_text().splitlines()[1:]]
    rows = sorted((r for r in rows if r["speed_index"] == 0), key=lambda r: r["index"])
    severity = [max(c["value"] / c["limit"] for c in r["checks"] if c["limit"] and c["value"] is not None)
                for r in rows]
    for entry in sensitivity["parameters"]:
        expected = stats.spearmanr([r["values"][entry["name"]] for r in rows], severity).statistic
        assert entry["spearman"] == pytest.approx(expected, rel=1e-9)
    assert [abs(e["spearman"]) for e in sensitivity["parameters"]] == sorted(
        (abs(e["spearman"]) for e in sensitivity["parameters"]), reverse=True)
    assert {e["name"] for e in sensitivity["parameters"]} == set(one["vary"])
    worst = one["worst_sample"]
    assert worst["canopen"]["report"] == "worst_sample.json" and not worst["passed"]
    report = json.loads((tmp_path / "one" / "worst_sample.json").read_text())
    assert report["passed"] == worst["canopen"]["passed"] and report["checks"]
    # the worst sample alone, from the scene and its index: the same report
    alone = subprocess.run([sys.executable, "-m", "ecam.app", "sweep", str(scene_file), "--sample",
                            str(worst["index"]), "--json"], capture_output=True, text=True)
    assert alone.returncode == (0 if worst["canopen"]["passed"] else 1), alone.stderr
    assert alone.stdout == (tmp_path / "one" / "worst_sample.json").read_text()
    with pytest.raises(AssertionError, match="yield of every check"):
        assert_yield(one, None, 0.95)
    assert_yield(one, "following_error", 1.0)
    # interrupted after three results: --resume runs the rest, and the summary is the same
    results = tmp_path / "one" / "results.jsonl"
    lines = results.read_text().splitlines()
    results.write_text("\n".join(lines[:4]) + "\n" + lines[4][:20])
    again, _ = _sweep(scene_file, tmp_path / "one", "--workers", "1", "--resume")
    assert again == one
    rows = [json.loads(line) for line in results.read_text().splitlines()[1:] if line.endswith("}")]
    assert len({(r["index"], r["speed_index"]) for r in rows}) == 12


def test_nominal_tuning_ships_the_nominal_gains_and_a_bad_sample_is_one_line(tmp_path):
    from ecam.app.sweep import plan_sweep, summarize
    from ecam.app.sweep_sample import run_sample

    # the efficiency beyond 1 for half the samples: those cannot run, the others can
    path = tmp_path / "bad.toml"
    path.write_text(_scene_text(
        "[sweep]\nsamples = 4\ntuning = 'nominal'\n[sweep.vary]\n"
        "'mechanics.gear_efficiency' = { distribution = 'uniform', low = 0.9, high = 1.1 }\n"))
    plan = plan_sweep(path)
    nominal = hil_sim.run_scene(load_scene(path).with_fidelity("full"), path="fast").to_dict()
    for key in ("position_kp", "velocity_kp", "velocity_ki"):  # the commissioning's gains, pinned
        assert plan.gains[key] == nominal["tuning"][key]
    assert plan.task(0, 0)["data"]["drive"]["gains"] == plan.gains
    results = {(i, 0): {**run_sample(plan.task(i, 0)), "values": plan.design.sample(i)}
               for i in range(4)}
    efficiency = plan.design.values[:, 0]
    bad = [i for i in range(4) if efficiency[i] > 1.0]
    assert 0 < len(bad) < 4  # a Latin hypercube puts two strata on each side of 1
    for i in bad:
        assert results[(i, 0)]["error"] == (
            f"scene bad.toml: mechanics.gear_efficiency: {efficiency[i]:.12g} should be <= 1")
    summary = summarize(plan, results)
    assert summary["errors"] == len(bad) and summary["passed"] <= 4 - len(bad)
    assert [e["index"] for e in summary["error_samples"]] == bad
    assert all(results[(i, 0)]["tuning"]["source"] == "scene" for i in range(4) if i not in bad)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:Port .* is already in use")
def test_a_sweep_runs_on_an_existing_scheduler(scene_file, tmp_path):
    from dask.distributed import LocalCluster

    from ecam.app.sweep import run_sweep

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        summary = run_sweep(scene_file, scheduler=cluster.scheduler_address,
                            directory=tmp_path / "out", samples=2, rerun_worst=False)
    assert summary["samples"] == 2 and summary["timing"]["scheduler"] == cluster.scheduler_address
    assert len((tmp_path / "out" / "results.jsonl").read_text().splitlines()) == 1 + 2 * 2


def test_a_sobol_design_gets_sobol_indices_and_falls_back_to_spearman_when_a_sample_errors(tmp_path):
    from ecam.app.sweep import plan_sweep, summarize

    path = tmp_path / "sobol.toml"
    path.write_text(_scene_text(SWEEP.replace("seed = 3", "seed = 3\nmethod = 'sobol'")
                                .replace("samples = 6", "samples = 80")))
    plan = plan_sweep(path)
    assert plan.design.samples == 16 * 5  # N (fields + 2), N = 16
    stiffness = plan.design.values[:, 0] / 2.0e6

    def result(i):  # a check that only the stiffness moves
        value = float(stiffness[i])
        return {"index": i, "speed_index": 0, "passed": value <= 1.1, "error": None,
                "values": plan.design.sample(i),
                "checks": [{"name": "made_up", "value": value, "limit": 1.1, "passed": value <= 1.1,
                            "unit": ""}]}

    results = {(i, k): result(i) for i in range(plan.design.samples) for k in range(2)}
    sensitivity = summarize(plan, results)["sensitivity"]
    assert sensitivity["method"] == "sobol"
    found = {p["name"]: p for p in sensitivity["parameters"]}
    # a field the output does not depend on has a total index of exactly 0 (Jansen's estimator
    # differences f(A) and f(A with that column from B), which are equal)
    assert found["mechanics.gear_backlash"]["ST"] == 0.0 == found["mechanics.load_inertia"]["ST"]
    assert found["mechanics.coupling_stiffness"]["ST"] > 0.5
    results[(3, 0)] = {**results[(3, 0)], "error": "made up", "checks": [], "passed": False}
    fallback = summarize(plan, results)["sensitivity"]
    assert fallback["method"] == "spearman" and "Sobol' indices need all of them" in fallback["note"]
    assert fallback["parameters"][0] == {"name": "mechanics.coupling_stiffness", "spearman": 1.0}


def test_a_sweep_is_bounded(tmp_path):
    from ecam.app.sweep import plan_sweep
    from ecam.errors import InputError

    path = tmp_path / "big.toml"
    path.write_text(_scene_text(SWEEP.replace("samples = 6", "samples = 600000")))
    with pytest.raises(InputError, match=r"^sweep: 600000 samples x 2 speeds = 1200000 runs should be <= 1000000$"):
        plan_sweep(path)
    many = "".join(f"'mechanics.load_inertia{i}' = {{ distribution = 'uniform', low = 0.01, high = 0.03 }}\n"
                   for i in range(101))
    with pytest.raises(CamFileError, match=r"sweep.vary: 101 fields should be at most 100$"):
        parse_sweep(_data("[sweep.vary]\n" + many), base=hil_sim.SCENES_DIR)
