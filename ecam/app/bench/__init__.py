"""`ecam bench`: error against bytes and lookup cost of the table kinds, against peers, and the
speed of the rig.

What runs
---------
For each cam (the laws cycloidal, poly345, modified_sine, harmonic as a rise over half the period
and its mirror-image return, and the seed cam ``combination_drrd``), each interpolation kind and a
range of point counts (``auto``: a range of tolerances; every kind also at the target tolerance,
1e-6 of the stroke), one table is compiled and certified, then timed:

- ``python_random`` / ``python_sequential``: :meth:`ecam.CamTable.lookup` (vectorized integer
  lookup, positions only) on random and on sequential master positions;
- ``c`` / ``c_sequential``: the C runtime (``firmware_tables/ecam_table.c``), driven by
  ``firmware_tables/ecam_bench.c``, compiled once per run with ``cc -O2 -std=c99`` (skipped, with
  a note, when there is no compiler); the driver times its own loop and returns a checksum of the
  positions, which must equal the Python lookup's on the same queries (``c_checksum_match``);
- peers on an equivalent float table (the same points, positions in float64):
  ``numpy_interp`` / ``numpy_interp_sequential`` (:func:`numpy.interp`), and, when scipy is
  installed (the ``bench`` extra), ``scipy_cubic`` (:class:`scipy.interpolate.CubicSpline`,
  periodic end conditions for a periodic cam) and ``scipy_pchip``
  (:class:`scipy.interpolate.PchipInterpolator`), on the random queries.

Every implementation gets the same query arrays (int64 counts; float64 copies for the peers):
``random`` is uniform over one master period, ``sequential`` a monotone ramp over the period, as
a streaming master produces. Times are medians of repeated runs (interleaved across the Python
and peer implementations, so drift hits all alike) in ns per lookup, and each is also given as
a ratio to ``numpy.interp`` on the same query set in the same run.

Scale: every cam is compiled with ``slave_counts_per_unit`` chosen so that its stroke is
``STROKE_COUNTS`` = 1e9 counts (int32 holds +-2.1e9) over ``MASTER_COUNTS`` = 1179648 master
counts per period. So 1e-6 of the stroke is 1000 counts, far above the 1/2-count quantization
floor, and the kinds separate by interpolation error rather than by rounding.

The rig: the shipped scene ``hil_sim/scenes/stiff_coupling.toml`` at 1 kHz and 4 kHz bus cycles
(the scene's ``cycle_s`` overridden), real-time factor and the cost split per cycle.

JSON shape (``--json``)
-----------------------
A list of rows, the table rows first; every row has the contract keys ``law``, ``interp``,
``points``, ``bytes``, ``max_error_counts``, ``ns_per_lookup`` (None on rows that are not tables)
and a ``kind``:

- ``"table"``: ``law``, ``interp`` (``auto`` rows also ``chosen_interp``), ``points``, ``bytes``,
  ``max_error_counts`` / ``max_error_units`` / ``max_error_fraction`` (the certificate's measured
  error, in counts, slave units and fractions of the stroke), ``predicted_error_counts`` (the
  certified bound), ``tolerance_fraction`` (or None), ``compile_s``, ``ns_per_lookup`` (an object
  keyed by implementation as above; None where one did not run), ``ratio_to_numpy_interp`` (the
  same keys; sequential timings are divided by ``numpy_interp_sequential``, the others by
  ``numpy_interp``), ``max_error_counts_on_queries`` (the error of the Python lookup and of each
  peer on the random queries), ``c_checksum_match`` (True, False or None).
- ``"rig"``: ``cycle_hz``, ``substeps``, ``real_time_factor`` (whole run, the effects'
  measurement included), ``effects_s`` and ``fidelity_runs`` (that measurement),
  ``loop_real_time_factor`` (the loop over CANopen), ``fast_real_time_factor`` (the same control
  and plant bus-free), ``us_per_cycle`` and ``cost_us_per_cycle`` (``lookup``, ``canopen``,
  ``drive_loop``, ``plant``), and ``available`` (always true: a rig that cannot run is an error
  of the bench, raised, never a row).
- ``"rig_search"``: find-max-speed on the scene: ``wall_s``, ``speed``, ``unit``,
  ``trials_fast``, ``trials_canopen``, ``limiting_check``, ``resolution``.
- ``"sweep"``: samples per second of a robustness sweep of the scene (:mod:`.sweep`): ``how``,
  ``workers``, ``samples``, ``wall_s``, ``samples_per_s``, ``steady_samples_per_s``,
  ``cluster_s``; the quick run times the samples in this process, the full run on a
  LocalCluster of 1 and 2 workers.
- ``"target"``: ``name``, ``value``, ``relation``, ``limit``, ``met``, ``factor`` (value / limit),
  ``verdict`` (one line saying met or missed and by how much), ``detail``.
- ``"note"``: ``text`` (the scale, the queries, what was skipped and why).

Targets are shown, never asserted: the numbers depend on the machine.
"""

from __future__ import annotations

from .c_runtime import CRuntime
from .plan import (BENCH_LAWS, IMPLEMENTATIONS, MASTER_COUNTS, SEED_CAM, STROKE_COUNTS, BenchPlan, bench_plan,
                   bench_profile, bench_queries, checksum, plan_jobs)
from .plot import pareto_front, plot_pareto, worst_over_cams
from .rig import bench_rig
from .run import main, run_bench
from .tables import LawContext, bench_table, median_ns
from .targets import TARGET_TEXT, evaluate_targets, target
from .text import CONTRACT_KEYS, contract_rows, format_text

__all__ = [
    "BENCH_LAWS", "BenchPlan", "CONTRACT_KEYS", "CRuntime", "IMPLEMENTATIONS", "LawContext", "MASTER_COUNTS",
    "SEED_CAM", "STROKE_COUNTS", "TARGET_TEXT", "bench_plan", "bench_profile", "bench_queries", "bench_rig",
    "bench_table", "checksum", "contract_rows", "evaluate_targets", "format_text", "main", "median_ns",
    "pareto_front", "plan_jobs", "plot_pareto", "run_bench", "target", "worst_over_cams",
]
