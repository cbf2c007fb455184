"""What a run records, cycle by cycle, in compact arrays: the same for a run over the bus
(:mod:`hil_sim.rig.loop`) and one without it (:mod:`hil_sim.rig.fast`).

Memory: 8 float64 series of one value per cycle (64 B), the plan's per-cycle arrays (about
60 B) and the bus's bits per cycle, plus the analysis' copies: measured, a run of 1e6 cycles
peaks at 257 MB against 56 MB for one of 1000 (``/usr/bin/time -v ecam sim``), about 0.2 kB per
cycle; :data:`hil_sim.scene.MAX_CYCLES` keeps a run within about 1 GB.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil_sim.control import ServoAxis
from hil_sim.drive.objects import FOLLOWING_ERROR_ACTUAL_VALUE, STATUSWORD

#: Series read from the drive's TPDOs (what a controller sees): object index -> name.
FROM_TPDOS = {STATUSWORD.index: "statusword", FOLLOWING_ERROR_ACTUAL_VALUE.index: "following_error"}
#: Series read from the axis after each cycle (what a real rig would measure at the load).
PROBED = ServoAxis.READINGS


@dataclass(frozen=True)
class Record:
    """What a run recorded: one value per cycle run, NaN where a TPDO never arrived.

    Attributes
    ----------
    cycles : int
        Cycles run; fewer than planned when a drive fault stopped the run.
    stopped : str or None
        Why the run stopped early (the fault, the cycle), None if it did not.
    statusword, following_error : numpy.ndarray
        From the drive's TPDOs (following error in counts, motor side).
    load_angle : numpy.ndarray
        Load angle [rad].
    coupling_torque : numpy.ndarray
        Coupling torque at the end of the cycle [N m].
    peak_coupling_torque, peak_twist, peak_motor_torque : numpy.ndarray
        Largest magnitudes within the cycle [N m, rad, N m] (twist: the coupling spring's).
    saturated : numpy.ndarray
        1.0 where the motor torque was clamped in the cycle, else 0.0.
    emcy : list of (float, int)
        (time [s], error code) of every EMCY the controller received.
    model, model_reason : str
        The plant the drive ran and why.
    setup : dict
        Facts of the set-up (:func:`hil_sim.rig.network.set_up_drive`).
    bus : dict
        :meth:`hil_sim.bus.BusLoad.summary` of the run, with what arbitration deferred.
    faults : dict or None
        :meth:`hil_sim.bus.FaultInjector.summary`, None without fault injection.
    path : str
        ``"canopen"`` (over the virtual bus) or ``"fast"`` (bus-free).
    """

    cycles: int
    stopped: str | None
    statusword: np.ndarray
    following_error: np.ndarray
    load_angle: np.ndarray
    coupling_torque: np.ndarray
    peak_coupling_torque: np.ndarray
    peak_twist: np.ndarray
    peak_motor_torque: np.ndarray
    saturated: np.ndarray
    emcy: list
    model: str
    model_reason: str
    setup: dict
    bus: dict
    faults: dict | None
    path: str = "canopen"


class Recorder:
    """The arrays of one run, filled cycle by cycle."""

    def __init__(self, cycles: int) -> None:
        self.series = {name: np.full(cycles, math.nan)
                       for name in (*FROM_TPDOS.values(), *PROBED)}
        self._probed = [self.series[name] for name in PROBED]
        self.ran = 0

    def probe(self, k: int, axis: ServoAxis) -> None:
        """Cycle ``k``'s readings of the axis."""
        for values, reading in zip(self._probed, axis.readings()):
            values[k] = reading

    def record(self, **facts) -> Record:
        """The record of the cycles run (``facts``: the Record's other fields)."""
        ran = self.ran
        return Record(cycles=ran, **{name: values[:ran] for name, values in self.series.items()},
                      **facts)
