"""Digital cam switches (tappets) on the rig: every edge's master position against the programmed
one, at the running speed, with and without the compensation.

The controller evaluates each track once per bus cycle on the master position it has then
(:func:`ecam.tappet.evaluate`, the integer form the C function computes bit for bit), with the
master's speed for the compensation, as a PLC's ``MC_DigitalCamSwitch`` does in its task. An
output edge reaches the process after the actuator's dead time; the track's compensation is set
to bring it forward by that time (PLCopen track ``OnCompensation`` / ``OffCompensation``: "For
negative values the switching time is brought forward"), so the actuator's dead time is taken as
-compensation (none where the compensation is >= 0). Where the master is when the actuator acts
is what the process sees: its distance from the programmed position is the edge's error. The same
track without compensation shows what the compensation gains (at speed v a dead time T moves the
edge by v T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ecam.tappet import TappetTrack, evaluate

__all__ = ["TappetEdges", "tappet_edges"]


@dataclass(frozen=True)
class TappetEdges:
    """One track's edges in a run.

    Attributes
    ----------
    name : str
    edges : int
        How many edges the track switched.
    worst : float
        The largest |actual - programmed| master position of an edge, compensated [master units].
    worst_uncompensated : float
        The same without the compensation [master units].
    worst_at_s : float
        When the worst compensated edge switched [s].
    rows : tuple of dict
        Each edge: ``time_s``, ``rising``, ``programmed``, ``actual``, ``error`` and
        ``error_uncompensated`` [master units].
    """

    name: str
    edges: int
    worst: float
    worst_uncompensated: float
    worst_at_s: float
    rows: tuple = ()

    def to_dict(self) -> dict:
        return {"name": self.name, "edges": self.edges, "worst": self.worst,
                "worst_uncompensated": self.worst_uncompensated, "worst_at_s": self.worst_at_s,
                "rows": list(self.rows)}


def tappet_edges(tracks, master, per_unit: float, period: float, master_counts: int,
                 cycle_s: float, cycles: int) -> tuple:
    """Each track's edges over a run.

    Parameters
    ----------
    tracks : sequence of ecam.tappet.TappetTrack
        In the master units of a cam of ``period``.
    master : object
        The master's motion in counts (``position(t)``, ``velocity(t)``).
    per_unit : float
        Master counts per master unit.
    period : float
        The cam's master period [master units].
    master_counts : int
        Master counts per period.
    cycle_s : float
    cycles : int

    Returns
    -------
    tuple of TappetEdges
    """
    times = np.arange(cycles) * cycle_s  # the controller's master of now, each cycle
    positions = np.rint(master.position(times)).astype(np.int64).tolist()
    speeds = np.clip(np.rint(master.velocity(times)), -2**31, 2**31 - 1).astype(np.int64).tolist()
    out = []
    for track in tracks:
        track = track.within(period)
        rows = _edges(track, track, master, per_unit, period, master_counts, times, positions, speeds)
        plain = replace(track, on_compensation=0.0, off_compensation=0.0)
        bare = _edges(plain, track, master, per_unit, period, master_counts, times, positions, speeds)
        worst = max(rows, key=lambda r: abs(r["error"]), default=None)
        for row, plain_row in zip(rows, bare):
            row["error_uncompensated"] = plain_row["error"]
        out.append(TappetEdges(track.name, len(rows), abs(worst["error"]) if worst else 0.0,
                               max((abs(r["error"]) for r in bare), default=0.0),
                               worst["time_s"] if worst else math.nan, tuple(rows)))
    return tuple(out)


def _edges(track: TappetTrack, programmed: TappetTrack, master, per_unit, period, master_counts,
           times, positions, speeds) -> list:
    """The edges of ``track`` with the dead times of ``programmed``'s compensation."""
    _, edges, _ = evaluate(track.to_counts(period, master_counts), positions, speeds)
    rows = []
    for edge in edges:
        rising = edge.rising
        target = programmed.on if rising else programmed.off
        compensation = programmed.on_compensation if rising else programmed.off_compensation
        dead_s = max(-compensation, 0.0)
        when = float(times[edge.index])
        actual = float(master.position(when + dead_s)) / per_unit % period
        error = (actual - target + period / 2) % period - period / 2
        rows.append({"time_s": when, "rising": rising, "programmed": target, "actual": actual,
                     "error": error})
    return rows
