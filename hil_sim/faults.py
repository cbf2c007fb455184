"""Faults on the bus, reproducibly: the plan a scene gives (:class:`Faults`) and its
application frame by frame (:class:`FaultInjector`).

Plain data and numpy only, no CAN stack: the scene reader checks a fault plan without loading
python-can or canopen (:mod:`hil_sim.bus`, which moves the frames, re-exports these names).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ecam.validate import choice, fail, integer, number, plain

__all__ = ["FRAME_KINDS", "MAX_SYNC_JITTER_S", "Faults", "FaultInjector", "DELIVER", "DROP"]

#: Frame kinds the fault injector knows (SYNC, PDOs from the controller, PDOs from the drive).
FRAME_KINDS = ("sync", "rpdo", "tpdo")
#: Largest SYNC jitter a fault plan may ask for [s]: a tenth of a second, far beyond any bus
#: cycle (at most 0.255 s, the 0x60C2 format), so every draw stays a small offset.
MAX_SYNC_JITTER_S = 0.1


@dataclass(frozen=True)
class Faults:
    """What goes wrong on the bus, reproducibly.

    Parameters
    ----------
    seed : int
        Seed of ``numpy.random.default_rng``; same seed, same faults.
    kinds : tuple of str
        Frame kinds the random drops and delays apply to, from ``("sync", "rpdo", "tpdo")``.
    drop_probability : float
        Probability that a frame of those kinds is lost, 0..1.
    drop : tuple of (int, str)
        Frames always lost: (cycle, kind) pairs.
    delay_probability : float
        Probability that a frame of those kinds (SYNC excepted) arrives whole cycles late.
    delay_cycles : int
        A delayed frame arrives 1..delay_cycles cycles late (uniform), >= 1.
    sync_jitter_s : float
        The controller's SYNC instants move by a uniform draw in [-jitter, +jitter] [s],
        0..MAX_SYNC_JITTER_S; the set points it sends are sampled at the jittered instant.

    Raises
    ------
    InputError
        A value out of range; the message names the parameter (``drop[1].frame``), the value
        and what was expected.
    """

    seed: int = 0
    kinds: tuple[str, ...] = ("rpdo", "tpdo")
    drop_probability: float = 0.0
    drop: tuple[tuple[int, str], ...] = ()
    delay_probability: float = 0.0
    delay_cycles: int = 1
    sync_jitter_s: float = 0.0

    def __post_init__(self) -> None:
        def store(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        store("seed", integer("seed", plain(self.seed), minimum=0))
        kinds = _sequence("kinds", self.kinds, f"a list of {', '.join(FRAME_KINDS)}")
        store("kinds", tuple(choice(f"kinds[{i}]", kind, FRAME_KINDS)
                             for i, kind in enumerate(kinds)))
        for name in ("drop_probability", "delay_probability"):
            store(name, number(name, plain(getattr(self, name)), minimum=0.0, maximum=1.0))
        drops = []
        for i, entry in enumerate(_sequence("drop", self.drop, "a list of (cycle, frame) pairs")):
            if not isinstance(entry, tuple) or len(entry) != 2:
                raise fail(f"drop[{i}]", entry, f"a pair (cycle >= 0, frame: one of "
                           f"{', '.join(FRAME_KINDS)})")
            drops.append((integer(f"drop[{i}].cycle", plain(entry[0]), minimum=0),
                          choice(f"drop[{i}].frame", entry[1], FRAME_KINDS)))
        store("drop", tuple(drops))
        store("delay_cycles", integer("delay_cycles", plain(self.delay_cycles), minimum=1))
        store("sync_jitter_s", number("sync_jitter_s", plain(self.sync_jitter_s), minimum=0.0,
                                      maximum=MAX_SYNC_JITTER_S))

    @property
    def active(self) -> bool:
        """True if any fault is configured."""
        return bool(self.drop_probability or self.drop or self.delay_probability or self.sync_jitter_s)


def _sequence(field: str, value, expected: str) -> tuple:
    """A tuple or list as a tuple (a string is refused: it is no list of names)."""
    if not isinstance(value, (tuple, list)):
        raise fail(field, value, expected)
    return tuple(value)


#: What :meth:`FaultInjector.decide` returns for a frame delivered on time.
DELIVER = 0
#: What :meth:`FaultInjector.decide` returns for a lost frame; a positive value is a delay in cycles.
DROP = -1


@dataclass
class FaultInjector:
    """Applies a :class:`Faults` plan frame by frame.

    The random draws happen in the order the rig asks, which is fixed by the scene (the rig is
    lock-step), so a run is reproducible. Counters of what was done are kept for the report.
    """

    faults: Faults
    cycle_s: float
    dropped: dict = field(default_factory=lambda: {kind: 0 for kind in FRAME_KINDS})
    delayed: dict = field(default_factory=lambda: {kind: 0 for kind in FRAME_KINDS})

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.faults.seed)
        self._explicit = set(self.faults.drop)
        self._random_kinds = frozenset(self.faults.kinds)

    def sync_offsets(self, cycles: int) -> np.ndarray:
        """SYNC jitter of ``cycles`` cycles [s] (zeros when none is configured).

        Drawn once, up front, from a generator of its own (seeded from the plan's seed), so the
        jitter does not depend on how many frame decisions came before.
        """
        jitter = self.faults.sync_jitter_s
        if not jitter:
            return np.zeros(cycles)
        rng = np.random.default_rng([self.faults.seed, 1])
        return rng.uniform(-jitter, jitter, cycles)

    def decide(self, cycle: int, kind: str) -> int:
        """Fate of one frame: :data:`DELIVER`, :data:`DROP`, or a delay in whole cycles (> 0)."""
        faults = self.faults
        if (cycle, kind) in self._explicit:
            self.dropped[kind] += 1
            return DROP
        if kind not in self._random_kinds:
            return DELIVER
        if faults.drop_probability and self._rng.random() < faults.drop_probability:
            self.dropped[kind] += 1
            return DROP
        if kind != "sync" and faults.delay_probability and self._rng.random() < faults.delay_probability:
            self.delayed[kind] += 1
            return int(self._rng.integers(1, faults.delay_cycles + 1))
        return DELIVER

    def summary(self) -> dict:
        """Counts of dropped and delayed frames by kind."""
        return {"dropped": dict(self.dropped), "delayed": dict(self.delayed),
                "sync_jitter_s": self.faults.sync_jitter_s, "seed": self.faults.seed}
