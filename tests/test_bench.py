"""`ecam bench`: the quick run's JSON contract, the plot, the checksum, the Pareto helper and the
target verdicts. No assertion on a time: the machines are noisy; a timeout only guards hangs."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ecam.errors import SimulationError

from ecam.app import bench

# Builds and times C and runs the bench: the full suite only (quick subset: -m "not slow").
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
CONTRACT = ("law", "interp", "points", "bytes", "max_error_counts", "ns_per_lookup", "ratio_to_numpy_interp")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _has_compiler() -> bool:
    return any(shutil.which(c) for c in (os.environ.get("CC", "cc"), "cc", "gcc", "clang") if c)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """One `ecam bench --quick --json --plot FILE` in a subprocess: (rows, plot path)."""
    plot = tmp_path_factory.mktemp("bench") / "pareto.png"
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run(
        [sys.executable, "-m", "ecam.app", "bench", "--quick", "--json", "--plot", str(plot)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout), plot


def _tables(rows):
    return [r for r in rows if r["kind"] == "table"]


def test_quick_json_is_a_list_of_rows_with_the_contract_fields(quick_run):
    rows, _ = quick_run
    assert isinstance(rows, list) and rows
    assert all(isinstance(r, dict) and r.get("kind") in {"table", "target", "rig", "rig_search", "sweep", "machine", "machine_scaling", "note"} for r in rows)
    assert all(field in r for r in rows for field in bench.CONTRACT_KEYS)  # every row: consumers never break
    kinds = [r["kind"] for r in rows]
    assert kinds == sorted(kinds, key=lambda k: k != "table")  # table rows first
    tables = _tables(rows)
    assert {r["interp"] for r in tables} == {"linear", "cubic", "quintic", "auto"}
    assert {"cycloidal", "combination_drrd"} <= {r["law"] for r in tables}
    for r in tables:
        for field in CONTRACT:
            assert field in r, (field, r)
        values_per_point = {"linear": 1, "cubic": 2, "quintic": 3}[r["chosen_interp"]]
        assert r["points"] >= 2 and r["bytes"] == 64 + 4 * r["points"] * values_per_point
        assert set(r["ns_per_lookup"]) == set(bench.IMPLEMENTATIONS)


def test_every_timing_is_positive_and_its_ratio_is_to_numpy_interp(quick_run):
    for r in _tables(quick_run[0]):
        ns, ratio = r["ns_per_lookup"], r["ratio_to_numpy_interp"]
        for key in ("python_random", "python_sequential", "numpy_interp", "numpy_interp_sequential"):
            assert ns[key] is not None and ns[key] > 0, (key, r)
        for key, value in ns.items():
            if value is None:
                assert ratio[key] is None
                continue
            assert value > 0 and math.isfinite(value), (key, r)
            base = ns["numpy_interp_sequential" if key.endswith("sequential") else "numpy_interp"]
            assert ratio[key] == pytest.approx(value / base, rel=1e-12)


def test_errors_agree_with_each_tables_certificate(quick_run):
    for r in _tables(quick_run[0]):
        assert 0 <= r["max_error_counts"] <= r["predicted_error_counts"], r
        assert r["max_error_units"] * r["slave_counts_per_unit"] == pytest.approx(r["max_error_counts"], rel=1e-9)
        assert r["max_error_fraction"] == pytest.approx(r["max_error_counts"] / r["stroke_counts"], rel=1e-9)
        # The certificate measured every master count; the random queries are some of them.
        assert r["max_error_counts_on_queries"]["python"] <= r["max_error_counts"] + 1e-6, r
        if r["tolerance_fraction"] is not None:
            assert r["max_error_fraction"] <= r["tolerance_fraction"], r


def test_c_runtime_agrees_bit_for_bit_when_a_compiler_exists(quick_run):
    rows = quick_run[0]
    notes = " | ".join(r["text"] for r in rows if r["kind"] == "note")
    if not _has_compiler():
        assert all(r["c_checksum_match"] is None for r in _tables(rows))
        assert "C runtime skipped" in notes
        return
    for r in _tables(rows):
        assert r["c_checksum_match"] is True, (r.get("c_error"), notes)
        assert r["ns_per_lookup"]["c"] > 0 and r["ns_per_lookup"]["c_sequential"] > 0


def test_targets_and_rig_rows_are_reported(quick_run):
    rows = quick_run[0]
    targets = {r["name"]: r for r in rows if r["kind"] == "target"}
    assert set(targets) == {
        "python_linear_vs_numpy_interp", "python_cubic_vs_numpy_interp", "python_quintic_vs_numpy_interp",
        "c_cubic_vs_c_linear", "auto_bytes_vs_linear_at_1e-6", "rig_real_time_factor_1khz",
        "rig_fast_path_real_time_factor_1khz",
    }
    for t in targets.values():
        assert t["relation"] in ("<=", ">=") and t["limit"] > 0 and t["verdict"]
        if t["met"] is not None:
            assert t["factor"] == pytest.approx(t["value"] / t["limit"])
    assert targets["auto_bytes_vs_linear_at_1e-6"]["met"] is not None  # pure bytes: always measurable
    rig = [r for r in rows if r["kind"] == "rig"]
    assert {r["cycle_hz"] for r in rig} == {1000, 4000}
    for r in rig:
        # An unavailable rig row is a failure of the bench, not a measurement.
        assert r["available"] is True, r.get("reason")
        assert r["real_time_factor"] > 0 and r["cycles"] > 0
        assert set(r["cost_us_per_cycle"]) == {"lookup", "canopen", "drive_loop", "plant"}
        assert r["fast_real_time_factor"] > r["loop_real_time_factor"] > 0  # bus-free is faster
        assert r["fidelity_runs"] >= 2 and r["effects_s"] > 0
    search = [r for r in rows if r["kind"] == "rig_search"]
    assert len(search) == 1 and search[0]["speed"] > 0 and search[0]["trials_canopen"] >= 1
    text = bench.format_text(rows)
    assert "targets (shown, not asserted)" in text and "cycloidal" in text


def test_quick_run_reports_the_machine_on_both_paths(quick_run):
    """The shipped machine: a row per path, and its one loop against its axes run alone."""
    rows = quick_run[0]
    machine = {r["path"]: r for r in rows if r["kind"] == "machine"}
    assert set(machine) == {"fast", "canopen"}
    for r in machine.values():
        assert r["axes"] == 6 and r["passed"] and r["real_time_factor"] > 0
        assert set(r["axis_s"]) == {"knife", "pusher", "lifter", "transfer", "feed", "turret"}
    scaling = {r["path"]: r for r in rows if r["kind"] == "machine_scaling"}
    assert set(scaling) == {"fast", "canopen"}
    for r in scaling.values():
        assert r["alone_sum_s"] == pytest.approx(sum(r["alone_s"].values()))
        assert r["ratio"] == pytest.approx(r["loop_s"] / r["alone_sum_s"])
    assert "one loop of 6 axes" in bench.format_text(rows)


def test_quick_run_reports_exact_instruction_counts(quick_run):
    """Instructions per lookup (runtime, minimal, ratio) on x86-64 and Cortex-M4 where the tools
    exist, else a note naming the missing tool; the counts are exact, so the verdict is asserted."""
    rows = quick_run[0]
    notes = [r for r in rows if r["kind"] == "note" and r.get("topic") in ("instructions", "cortex-m4")]
    text = bench.format_text(rows)
    assert "instructions per lookup: exact counts" in text
    for target in ("x86-64", "cortex-m4"):
        measured = [r for r in notes if r.get("target") == target and "instructions_minimal" in r]
        if not measured:
            why = " ".join(r["text"] for r in notes if r.get("target") == target)
            assert "not measured" in why and "not found" in why, why
            continue
        assert {r["interp"] for r in measured} == {"linear", "cubic", "quintic"}
        for r in measured:
            assert r["checksums_match"] is True, r["text"]
            assert 0 < r["instructions_minimal"] and 0 < r["instructions_runtime_inside"] < r["instructions_runtime_wide"]
            assert r["ratio_inside"] == pytest.approx(r["instructions_runtime_inside"] / r["instructions_minimal"])
            assert r["ratio_wide"] == pytest.approx(r["instructions_runtime_wide"] / r["instructions_minimal"])
            assert (r["limit_inside"], r["limit_wide"]) == (2.0, 3.0)
            assert r["met"] is True, r["text"]
            line = next(x for x in text.splitlines() if x.split()[:3] == [target, r["cam"], r["interp"]])
            assert f"{r['ratio_inside']:.2f}x" in line and line.endswith("met")
    footprint = [r for r in notes if r.get("topic") == "cortex-m4" and "flash_bytes" in r]
    if footprint:
        assert [r["opt"] for r in footprint] == ["-Os", "-O2"]
        for r in footprint:
            assert r["flash_bytes"] > 0 and r["ram_bytes"] == 0 and r["table_bytes"] > 0
            assert 0 < r["stack_per_call_max"]["position"] <= 64 and 0 < r["stack_per_call_max"]["slope"] <= 64
            line = next(x for x in text.splitlines() if x.split()[:2] == [r["opt"], str(r["flash_bytes"])])
            assert f"{r['stack_per_call_max']['position']} B" in line, line


def test_plot_writes_a_png(quick_run):
    _, plot = quick_run
    assert plot.is_file()
    assert plot.read_bytes()[:8] == PNG_MAGIC


def test_pareto_front_picks_the_non_dominated_points():
    points = [
        (1.0, 10.0),   # 0: front (cheapest)
        (2.0, 5.0),    # 1: front
        (2.0, 6.0),    # 2: dominated by 1
        (3.0, 5.0),    # 3: dominated by 1
        (4.0, 1.0),    # 4: front
        (5.0, 1.0),    # 5: dominated by 4
        (0.5, 20.0),   # 6: front (cheaper than all)
        (4.0, 1.0),    # 7: equal to 4: not dominated
        (None, 0.1),   # 8: ignored
        (6.0, math.nan),  # 9: ignored
        (10.0, 0.5),   # 10: front (most accurate)
    ]
    assert bench.pareto_front(points) == [6, 0, 1, 4, 7, 10]
    assert bench.pareto_front([]) == []
    assert bench.pareto_front([(1.0, 1.0)]) == [0]


def test_checksum_is_the_drivers_formula():
    p = np.array([3, -1, 2**31 - 1, -(2**31)], dtype=np.int64)
    n = len(p)
    s1 = sum(int(v) for v in p) % 2**64
    s2 = sum((n - k) * int(v) for k, v in enumerate(p)) % 2**64
    assert bench.checksum(p) == (s1 + s2 * 0x9E3779B97F4A7C15) % 2**64
    assert bench.checksum(p[::-1]) != bench.checksum(p)  # the order counts


def test_target_verdicts_say_by_how_much():
    missed = bench.target("x", 0.5, "<=", 0.25, {}, "")
    assert missed["met"] is False and "MISSED by 2x" in missed["verdict"]
    short = bench.target("y", 10.0, ">=", 20.0, {}, "")
    assert short["met"] is False and "MISSED by 2x" in short["verdict"] and "50% short" in short["verdict"]
    met = bench.target("z", 0.05, "<=", 0.1, {}, "")
    assert met["met"] is True and "2x margin" in met["verdict"]
    assert bench.target("w", None, "<=", 1.0, {}, "no data")["met"] is None


def test_worst_over_cams_takes_the_largest_error_and_bytes():
    def row(law, error, size, ns):
        return {"law": law, "interp": "cubic", "points": 145, "tolerance_fraction": None, "bytes": size,
                "max_error_fraction": error, "ns_per_lookup": dict.fromkeys(bench.IMPLEMENTATIONS, ns)}

    rows = [row("a", 1e-7, 1224, 10.0), row("b", 3e-7, 1224, 14.0), row("c", 2e-7, 1224, 12.0)]
    (config,) = bench.worst_over_cams(rows)
    assert config["max_error_fraction"] == 3e-7 and config["bytes"] == 1224 and config["cams"] == 3
    assert config["ns_per_lookup"]["c"] == 12.0


def test_a_table_row_without_scipy_or_c_leaves_those_timings_empty():
    plan = bench.BenchPlan(laws=("cycloidal",), intervals={}, auto_tolerances=(), kind_tolerances=(),
                           queries=512, repeats=1, rig_repeats=1)
    ctx = bench.LawContext("cycloidal", bench.bench_queries(plan.queries))
    row = bench.bench_table(ctx, {"law": "cycloidal", "interp": "cubic", "intervals": 144}, plan, None, [], None)
    for key in ("c", "c_sequential", "scipy_cubic", "scipy_pchip"):
        assert row["ns_per_lookup"][key] is None and row["ratio_to_numpy_interp"][key] is None
    assert row["c_checksum_match"] is None and row["points"] == 145
    assert set(row["max_error_counts_on_queries"]) == {"python", "numpy_interp"}


def test_no_compiler_gives_a_note_not_a_crash(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv("CC", raising=False)
    runtime = bench.CRuntime(tmp_path)
    assert runtime.executable is None and "no C compiler" in runtime.note


def test_a_broken_rig_is_an_error_not_a_row(monkeypatch):
    import ecam.app.bench.rig

    def broken(scene, **kwargs):
        raise SimulationError("scene x: broken on purpose")

    monkeypatch.setattr(ecam.app.bench.rig, "run_scene", broken)
    with pytest.raises(SimulationError, match="broken on purpose"):
        bench.bench_rig(repeats=1)
