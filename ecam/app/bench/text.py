"""The bench as text, and the `--json` rows with the contract keys."""

from __future__ import annotations

from .machine import machine_lines
from .sweep import sweep_lines
from .targets import TARGET_TEXT


def _cell(value, fmt="{:.1f}", width=7):
    return f"{'-' if value is None else fmt.format(value):>{width}s}"


def format_text(rows: list[dict]) -> str:
    """The human report: notes, the table, the rig and the targets."""
    lines = ["ecam bench: error against bytes and lookup cost of the cam-table kinds", ""]
    lines += [f"  {r['text']}" for r in rows if r.get("kind") == "note" and r.get("topic") not in _COUNT_TOPICS]
    lines += [
        "",
        "  err: the certificate's measured max error over every master count (bound: its certified bound);",
        "  ns: median ns per lookup; py/np, pyseq/, C/np: ratio to numpy.interp on the same queries",
        "  (pyseq/: Python sequential / numpy.interp sequential);",
        "  peers use the same points in float64: np = numpy.interp, CS = scipy CubicSpline, PC = scipy Pchip;",
        "  C ok: the C checksum equals the Python lookup's on both query sets.",
        "",
    ]
    head = (f"{'law':16s} {'interp':14s} {'tol':>6s} {'points':>6s} {'bytes':>7s} {'err cnt':>9s} {'err/strk':>8s} "
            f"{'bound':>9s} {'comp ms':>7s} | {'py rnd':>7s} {'py seq':>7s} {'C rnd':>7s} {'C seq':>7s} "
            f"{'np rnd':>7s} {'np seq':>7s} {'CS':>7s} {'PC':>7s} | "
            f"{'py/np':>6s} {'pyseq/':>6s} {'C/np':>6s} {'C ok':>4s}")
    lines += [head, "-" * len(head)]
    for r in rows:
        if r.get("kind") != "table":
            continue
        ns, ratio = r["ns_per_lookup"], r["ratio_to_numpy_interp"]
        interp = r["interp"] if r["interp"] != "auto" else f"auto:{r['chosen_interp']}"
        tol = "" if r["tolerance_fraction"] is None else f"{r['tolerance_fraction']:.0e}"
        ok = {True: "yes", False: "NO", None: "-"}[r["c_checksum_match"]]
        lines.append(
            f"{r['law']:16s} {interp:14s} {tol:>6s} {r['points']:6d} {r['bytes']:7d} {r['max_error_counts']:9.3g} "
            f"{r['max_error_fraction']:8.1e} {r['predicted_error_counts']:9.3g} {1e3 * r['compile_s']:7.0f} | "
            + " ".join(_cell(ns[k]) for k in ("python_random", "python_sequential", "c", "c_sequential",
                                               "numpy_interp", "numpy_interp_sequential", "scipy_cubic", "scipy_pchip"))
            + " | " + " ".join(_cell(ratio[k], "{:.2f}x", 6) for k in ("python_random", "python_sequential", "c"))
            + f" {ok:>4s}")
    rig = [r for r in rows if r.get("kind") == "rig"]
    if rig:
        lines += ["", "rig (the shipped scene, cycle time overridden; median run):"]
    for r in rig:  # every rig row is a measurement: a rig that cannot run raises (bench_rig)
        c = r["cost_us_per_cycle"]
        split = ", ".join(f"{name} {_cell(c[key], '{:.2f}', 0).strip()} us"
                          for key, name in (("lookup", "lookup"), ("canopen", "CANopen"),
                                            ("drive_loop", "drive loop"), ("plant", "plant")))
        lines.append(
            f"  {r['scene']} at {r['cycle_hz'] / 1000:g} kHz ({r['substeps']} controller periods a "
            f"cycle): {r['cycles']} cycles ({r['simulated_s']:.3g} s simulated) in {r['wall_s']:.3g} s: "
            f"real-time factor {r['real_time_factor']:.3g}x (effects measured in {r['effects_s']:.3g} s "
            f"on {r['fidelity_runs']} bus-free runs); loop over CANopen {r['loop_real_time_factor']:.3g}x, "
            f"bus-free {r['fast_real_time_factor']:.3g}x real time; "
            f"{r['us_per_cycle']:.1f} us per cycle: {split}; setup {1e3 * r['setup_s']:.0f} ms; "
            f"checks {'passed' if r['passed'] else 'failed: ' + ', '.join(r['failed_checks'])}")
    notes = next((r.get("notes") for r in rig if r.get("notes")), None)
    if notes:
        lines += [f"  ({n})" for n in notes]
    for r in (r for r in rows if r.get("kind") == "rig_search"):
        found = "none" if r["speed"] is None else f"{r['speed']:.4g} {r['unit']}"
        lines.append(f"  find-max-speed on {r['scene']}: {found} in {r['wall_s']:.3g} s "
                     f"({r['trials_fast']} bus-free trials, {r['trials_canopen']} over CANopen; "
                     f"resolution {r['resolution']:.3g} {r['unit']})")
    lines += sweep_lines(rows)
    lines += machine_lines(rows)
    lines += _instruction_lines(rows)
    targets = [r for r in rows if r.get("kind") == "target"]
    if targets:
        lines += ["", "targets (shown, not asserted):"]
    for t in targets:
        mark = {True: "met   ", False: "MISSED", None: "n/a   "}[t["met"]]
        value = "-" if t["value"] is None else f"{t['value']:.3g}"
        lines.append(f"  [{mark}] {TARGET_TEXT.get(t['name'], t['name'])}: {value} -> {t['verdict']}")
    return "\n".join(lines) + "\n"


_COUNT_TOPICS = ("instructions", "cortex-m4")


def _instruction_lines(rows: list[dict]) -> list[str]:
    """Instructions per lookup (exact counts) and the Cortex-M4 footprint."""
    counted = [r for r in rows if r.get("kind") == "note" and r.get("topic") in _COUNT_TOPICS]
    if not counted:
        return []
    lines = ["", "instructions per lookup: exact counts (callgrind on x86-64, a QEMU trace on Cortex-M4) of one",
             "ecam_table_position call against ecam_minimal.c, the same table's lookup hand-written with its",
             "format as constants and the master already in [0, M); inside = masters in [0, M), wide = any",
             "int64 (each one wraps); limits 2x inside, 3x wide:"]  # fmt: skip
    head = (f"  {'target':9s} {'cam':16s} {'interp':7s} {'points':>6s} {'h':>6s} {'net':>8s} | {'inside':>6s} "
            f"{'wide':>6s} {'minimal':>7s} | {'in/min':>6s} {'wide/min':>8s}  verdict")
    table = [r for r in counted if "instructions_minimal" in r]
    if table:
        lines += [head, "  " + "-" * (len(head) - 2)]
    for r in table:
        verdict = "met" if r["met"] else "MISSED" + ("" if r["checksums_match"] else " (checksums differ)")
        net = r.get("net_stroke", "0")
        lines.append(f"  {r['target']:9s} {r.get('cam', ''):16s} {r['interp']:7s} {r['points']:6d} {r['step_counts']:6d} "
                     f"{'-' if net == '0' else net:>8s} | {r['instructions_runtime_inside']:6.1f} "
                     f"{r['instructions_runtime_wide']:6.1f} {r['instructions_minimal']:7.1f} | "
                     f"{r['ratio_inside']:5.2f}x {r['ratio_wide']:7.2f}x  {verdict}")
    expanded = [r for r in table if "instructions_q16" in r]
    if expanded:
        lines += ["", "the expanded form (ecam_poly_position, each interval's polynomial precomputed into RAM at init)",
                  "against the minimal lookup of the same degree with precomputed coefficients (int32 words, Q16",
                  "fraction, no wrap: ecam_minimal_q16_*) and against its own format hand-written",
                  "(ecam_minimal_expanded_*, the same bits); horner 32 = a table compiled with horner_bits=32,",
                  "whose expansion runs in 32-bit words on 32-bit cores; limits for quintic 1.5x inside, 2x wide:"]
        head = (f"  {'target':9s} {'cam':16s} {'interp':7s} {'points':>6s} {'horner':>6s} | {'inside':>6s} {'wide':>6s} "
                f"{'same':>6s} {'q16':>6s} | {'in/q16':>6s} {'wide/q16':>8s} {'hermite/q16':>11s}  verdict")
        lines += [head, "  " + "-" * (len(head) - 2)]
        for r in expanded:
            verdict = {True: "met", False: "MISSED", None: "-"}[r["poly_met"]]
            lines.append(f"  {r['target']:9s} {r.get('cam', ''):16s} {r['interp']:7s} {r['points']:6d} "
                         f"{r['horner_bits']:6d} | {r['instructions_poly_inside']:6.1f} {r['instructions_poly_wide']:6.1f} "
                         f"{r['instructions_expanded']:6.1f} {r['instructions_q16']:6.1f} | {r['ratio_poly_inside']:5.2f}x "
                         f"{r['ratio_poly_wide']:7.2f}x {r['ratio_runtime_q16']:10.2f}x  {verdict}")
    footprint = [r for r in counted if "flash_bytes" in r]
    if footprint:
        lines += ["", "Cortex-M4 footprint of ecam_table.o (flash, static RAM, struct sizes) and stack per call",
                  "(measured by painting the stack under QEMU, masters inside and outside the period):"]
        head = (f"  {'opt':4s} {'flash':>8s} {'RAM':>5s} {'table':>6s} {'pair':>6s} | {'position':>8s} {'slope':>6s} "
                f"{'lookup':>7s} {'init':>6s} | with a net stroke: position, lookup")
        lines += [head, "  " + "-" * (len(head) - 2)]
        for r in footprint:
            worst, net = r["stack_per_call_max"], r.get("stack_per_call_max_net_stroke") or {}
            init = max(v["init"] for v in r["stack_per_call"].values())
            with_net = "-" if net.get("position") is None else f"{net['position']} B, {net['lookup']} B"
            lines.append(f"  {r['opt']:4s} {r['flash_bytes']:6d} B {r['ram_bytes']:3d} B {r['table_bytes']:4d} B "
                         f"{r['pair_bytes']:4d} B | {worst['position']:6d} B {worst['slope']:4d} B {worst['lookup']:5d} B "
                         f"{init:4d} B | {with_net}")
    lines += [f"  {r['text']}" for r in counted if "instructions_minimal" not in r and "flash_bytes" not in r]
    return lines


# --- command line -------------------------------------------------------------------------------


CONTRACT_KEYS = ("law", "interp", "points", "bytes", "max_error_counts", "ns_per_lookup")


def contract_rows(rows: list[dict]) -> list[dict]:
    """The ``--json`` list: the table rows first, then the rig, target and note rows; every row
    carries the contract keys (None where a row is not a table), so a consumer that reads
    ``row["law"]`` or ``row["bytes"]`` on every row does not break."""
    ordered = [r for r in rows if r.get("kind") == "table"] + [r for r in rows if r.get("kind") != "table"]
    return [{**{key: None for key in CONTRACT_KEYS}, **row} for row in ordered]
