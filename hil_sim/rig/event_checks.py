"""The report's lines for a scene's events (:mod:`hil_sim.events`) and tappets
(:mod:`hil_sim.tappet_edges`): each switch with the jump it made, the phase shifts' and
cam-outs' peaks against their limits, and the tappet edges against the programmed positions.
None of them for a scene without events or tappets: its report is as it was."""

from __future__ import annotations

import numpy as np

from hil_sim.report import Check, check

#: ruckig's own tolerance contract (its README: position and velocity 1e-8): a profile's peak
#: at its limit is compared after rounding off what lies below it.
_RUCKIG_DIGITS = 8


def event_checks(run) -> tuple[list[Check], dict, dict]:
    """(checks, summary entries, series) of the run's events and tappets."""
    plan, profile = run.plan, run.cam.profile
    master_unit, slave_unit = profile.master_unit, profile.slave_unit
    checks, summary, series = [], {}, {}
    outcome = plan.events
    if outcome is not None:
        summary["events"] = outcome.to_dict()
        if outcome.switches:
            checks.append(_switch_check(outcome.switches, slave_unit, master_unit))
        if outcome.motions:
            checks.append(_motion_check(outcome.motions, master_unit, slave_unit))
        if outcome.phase is not None:
            series["phase_shift"] = np.asarray(outcome.phase)
        series["event_reference"] = np.asarray(plan.reference_units)  # the events panel's path
    if plan.tappets:
        summary["tappets"] = [t.to_dict() for t in plan.tappets]
        checks.append(_tappet_check(plan.tappets, run.scene.limits.tappet_error, master_unit))
    return checks, summary, series


def _switch_check(switches, slave_unit: str, master_unit: str) -> Check:
    """The switches that jump where the scene does not allow it (a count, limit 0)."""
    lines = []
    for s in switches:
        what = f"{s.event.label} {s.event.action} to {s.cam or 'the running cam'} ({s.event.activation})"
        if s.superseded_by:
            lines.append(f"{what}: superseded by {s.superseded_by} before it activated")
            continue
        if s.active_s is None:
            lines.append(f"{what}: not reached within the run")
            continue
        allowed = " (allowed)" if s.errors and s.event.allow_jump else ""
        lines.append(f"{what} at {s.active_s:.6g} s, master {s.master:.6g} {master_unit}: "
                     f"{s.jump_text(slave_unit, master_unit)}{allowed}")
    failed = sum(1 for s in switches if s.failed)
    return check("switch_jumps", failed, 0, "count", "; ".join(lines))


def _motion_check(motions, master_unit: str, slave_unit: str) -> Check:
    """The phase shifts' and cam-outs' peaks against their limits, as a share of the limit."""
    worst = max(motions, key=lambda m: m.ratio)
    lines = []
    for m in motions:
        unit = master_unit if m.event.action == "phase" else slave_unit
        peaks = ", ".join(f"{name} {p:.4g}/{lim:.4g}" for name, p, lim in
                          zip(("velocity", "acceleration", "jerk"), m.peaks, m.limits))
        lines.append(f"{m.event.label} {m.event.action} at {m.start_s:.6g} s for "
                     f"{m.duration_s:.4g} s, {m.covered:+.6g} {unit} ({peaks} {unit}/s^n)")
    value = round(100.0 * worst.ratio, _RUCKIG_DIGITS - 2)
    return check("event_motion", value, 100.0, "%", "; ".join(lines))


def _tappet_check(tracks, limit, master_unit: str) -> Check:
    """The largest edge error with compensation; without it, in the detail."""
    lines = [f"{t.name or f'tappet[{i}]'}: {t.edges} edges, worst {t.worst:.4g} {master_unit}"
             f" (without compensation {t.worst_uncompensated:.4g})"
             for i, t in enumerate(tracks)]
    worst = max(t.worst for t in tracks)
    return check("tappet_edges", worst, limit, master_unit, "; ".join(lines))
