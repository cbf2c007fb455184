"""What a bench run measures: the plan, the cams at the bench scale, the queries, the checksum."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ecam.camfile import CAMS_DIR, load_cam, parse_cam
from ecam.table import KINDS

MASTER_COUNTS = 9 * 2**17  # 1179648: every 20-degree joint of the seed and every 1/16 period on a power-of-two step
STROKE_COUNTS = 1e9  # slave counts of every cam's stroke (positions stay inside int32)
BENCH_LAWS = ("cycloidal", "poly345", "modified_sine", "harmonic")  # each as a rise and its mirrored return
SEED_CAM = "combination_drrd"
TARGET_FRACTION = 1e-6  # of the stroke, for the bytes target
RIG_CYCLES_HZ = (1000, 4000)
RIG_SCENE = "stiff_coupling.toml"
_MIX = 0x9E3779B97F4A7C15  # checksum mixing constant, as in ecam_bench.c
_RANDOM_SEED = 20240917

# Implementation keys of ns_per_lookup, and which numpy.interp timing each is a ratio to.
IMPLEMENTATIONS = ("python_random", "python_sequential", "c", "c_sequential", "numpy_interp",
                   "numpy_interp_sequential", "scipy_cubic", "scipy_pchip")
SEQUENTIAL = {"python_sequential", "c_sequential", "numpy_interp_sequential"}


@dataclass(frozen=True)
class BenchPlan:
    """What one run measures. Intervals per kind are divisors of MASTER_COUNTS that put every
    joint of the cams on a table point; tolerances are fractions of the stroke."""

    laws: tuple[str, ...]
    intervals: dict
    auto_tolerances: tuple[float, ...]
    kind_tolerances: tuple[str, ...]  # kinds also compiled at TARGET_FRACTION
    queries: int
    repeats: int
    rig_repeats: int


def bench_plan(quick: bool) -> BenchPlan:
    """The full plan (about two minutes) or the quick one (seconds, for CI smoke tests)."""
    if quick:
        return BenchPlan(
            laws=("cycloidal", SEED_CAM),
            intervals={"linear": (144,), "cubic": (144,), "quintic": (144,)},
            auto_tolerances=(TARGET_FRACTION,),
            kind_tolerances=("linear",),
            queries=2**14, repeats=3, rig_repeats=1,
        )
    return BenchPlan(
        laws=(*BENCH_LAWS, SEED_CAM),
        intervals={"linear": (144, 576, 2304, 9216, 36864), "cubic": (36, 144, 576, 2304, 9216),
                   "quintic": (18, 72, 288, 1152, 4608)},
        auto_tolerances=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8),
        kind_tolerances=tuple(KINDS),
        queries=2**18, repeats=7, rig_repeats=3,
    )


# --- cams and queries -----------------------------------------------------------------------------


def bench_profile(name: str):
    """The cam of one bench row: a law as a rise over half the period and its mirror-image
    return (periodic, stroke 1 'stroke' unit), or the seed cam file of that name."""

    if name in BENCH_LAWS:
        return parse_cam({
            "name": name, "master_period": 360.0, "periodic": True, "master_unit": "deg",
            "slave_unit": "stroke",
            "segment": [{"law": name, "span": 180.0, "stroke": 1.0},
                        {"law": name, "span": 180.0, "stroke": -1.0}],
        }, source=f"<bench {name}>")
    return load_cam(CAMS_DIR / f"{name}.toml")


def bench_queries(count: int, master_counts: int = MASTER_COUNTS, seed: int = _RANDOM_SEED):
    """(random, sequential) int64 master positions: uniform over [0, M), and a monotone ramp
    from 0 to M - 1 (a master streaming through one period)."""
    rng = np.random.default_rng(seed)
    random = rng.integers(0, master_counts, size=count, dtype=np.int64)
    sequential = np.rint(np.linspace(0, master_counts - 1, count)).astype(np.int64)
    return random, sequential


def checksum(positions) -> int:
    """The checksum ecam_bench.c prints: s1 = sum p[k], s2 = sum (n - k) p[k], both mod 2^64,
    returned as (s1 + s2 * 0x9E3779B97F4A7C15) mod 2^64."""
    p = np.asarray(positions, dtype=np.int64).astype(np.uint64)
    n = p.size
    with np.errstate(over="ignore"):
        s1 = int(p.sum(dtype=np.uint64))
        s2 = int((p * (n - np.arange(n, dtype=np.uint64))).sum(dtype=np.uint64))
    return (s1 + s2 * _MIX) % 2**64


def plan_jobs(plan: BenchPlan) -> list[dict]:
    jobs = []
    for law in plan.laws:
        for kind in KINDS:
            for intervals in plan.intervals[kind]:
                jobs.append({"law": law, "interp": kind, "intervals": intervals})
        for kind in plan.kind_tolerances:
            jobs.append({"law": law, "interp": kind, "tolerance_fraction": TARGET_FRACTION})
        for tolerance in plan.auto_tolerances:
            jobs.append({"law": law, "interp": "auto", "tolerance_fraction": tolerance})
    return jobs
