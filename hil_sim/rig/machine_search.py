"""The highest master speed at which a whole machine passes, and the station and the check that
limit it: :func:`hil_sim.rig.search.search_speed` (the scene's search, unchanged) with a
machine's trials. Each trial runs every axis from the one virtual master at the trial's speed,
until every axis has reached cruise and its settling time and then
:data:`~hil_sim.rig.search.PERIODS_AT_CRUISE` master periods; every axis is commissioned once,
as for a single scene."""

from __future__ import annotations

from dataclasses import replace

from hil_sim.machine import Machine, load_machine
from hil_sim.rig.machine_run import run_machine
from hil_sim.rig.run import commission
from hil_sim.rig.search import search_speed, trial_scene
from hil_sim.rig.stability import verdict_kind
from hil_sim.scene import DurationSpec


def trial_machine(machine: Machine, speed: float) -> Machine:
    """The machine at ``speed`` [the first axis's master units/s; every axis at the same master
    periods per second], every axis run as long as the longest needs
    (:func:`hil_sim.rig.search.trial_scene`)."""
    first = machine.axes[0].cam.load_profile().master_period
    trials = [trial_scene(axis, speed * axis.cam.load_profile().master_period / first)
              for axis in machine.axes]
    seconds = max(t.duration.seconds for t in trials)
    return replace(machine, axes=tuple(replace(t, duration=DurationSpec(seconds=seconds))
                                       for t in trials))


class MachineTrials:
    """What the search varies and runs for a machine (:class:`hil_sim.rig.search.SceneTrials`'
    counterpart): the machine at a speed, each axis commissioned once."""

    def __init__(self, machine: Machine):
        self.machine = machine

    def profile(self):
        """The first axis's cam profile: the speed is given in its master units."""
        return self.machine.axes[0].cam.load_profile()

    def start_speed(self, profile) -> float:
        return self.machine.axes[0].master.units_per_second(profile.master_period)

    def commission(self) -> list:
        return [commission(axis) for axis in self.machine.axes]

    def run(self, speed: float, path: str, tunings: list):
        """The trial at ``speed``: bus-free with every effect on (an ideal axis stays ideal),
        over CANopen with each axis's own fidelity."""
        machine = trial_machine(self.machine, speed)
        if path == "fast":
            machine = replace(machine, axes=tuple(
                a.with_fidelity("ideal" if a.fidelity == "ideal" else "full")
                for a in machine.axes))
        return run_machine(machine, path=path, tunings=tunings)

    def simulated_s(self, report) -> float:
        return report.cycles * self.machine.cycle_s

    def limiting(self, check) -> dict:
        """The station (axis) whose check limits the machine (None: the machine's own bus or
        faults check) and whose limit that check is."""
        for axis in self.machine.axes:
            prefix = axis.name + "."
            if check.name.startswith(prefix):
                return {"limiting_station": axis.name,
                        "limiting_kind": verdict_kind(check.name[len(prefix):])}
        return {"limiting_station": None, "limiting_kind": verdict_kind(check.name)}


def find_machine_max_speed(machine, *, tolerance: float = 0.01, max_runs: int = 40,
                           progress=None) -> dict:
    """Highest master speed at which the machine's checks and every axis's pass.

    Parameters
    ----------
    machine : Machine or str or Path
        The machine (or its file); its master speed is the starting point.
    tolerance, max_runs, progress
        As :func:`hil_sim.rig.search.find_max_speed`.

    Returns
    -------
    dict
        :func:`hil_sim.rig.search.find_max_speed`'s result (the speed in the first axis's
        master units/s, ``periods_per_minute`` the machine's cycles per minute), with
        ``limiting_station``: the axis whose check limits the machine (None when the machine's
        own ``bus_load`` or ``faults`` does), its check named ``<axis>.<check>``.
    """
    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    return search_speed(MachineTrials(machine), tolerance=tolerance, max_runs=max_runs,
                        progress=progress)
