"""The ``[sweep]`` table of a scene: a robustness sweep over manufacturing spread.

Read and checked here, where it enters (the rig ignores the table when it runs the scene
itself); run by ``ecam sweep`` (:mod:`ecam.app.sweep`). Layout::

    [sweep]
    samples = 200                  # rows of the design (grid and sobol round down)
    seed = 1                       # 0 .. 2^63-1: the design and each sample's own seed
    method = "latin_hypercube"     # "latin_hypercube", "monte_carlo", "grid" (1 or 2 fields),
                                   # "sobol" (Saltelli's design: Sobol' indices, needs SALib)
    speeds = [360.0, 400.0]        # master units/s to judge at; or speeds_rpm = [...];
                                   # default: the scene's own speed
    required_yield = 0.95          # the yield the fastest speed must reach
    confidence = 0.95              # the level of the yield's (Wilson) interval
    tuning = "per_sample"          # "per_sample": each sample commissioned on its own, as each
                                   # machine built would be; "nominal": the nominal machine's
                                   # tuning shipped to every sample
    fidelity = "full"              # the effects each sample models (hil_sim.effects); "full"
                                   # skips the per-run measurement of "auto" (as find-max-speed)

    [sweep.vary]                   # a scene field by its dotted name -> its distribution
    "mechanics.coupling_stiffness" = { distribution = "normal", mean = 1.0, std = 0.15, relative = true }
    "mechanics.gear_backlash" = { distribution = "uniform", low = 0.0, high = 0.0015 }
    "mechanics.load_inertia" = { distribution = "triangular", low = 0.9, mode = 1.0, high = 1.3,
                                 relative = true, maximum = 1.2 }

A dotted name reaches into nested tables (``drive.gains.velocity_bandwidth_hz``) and into
arrays of tables with an index (``axis[1].mechanics.load_inertia``). A relative distribution
is a factor on the scene's own value (which the scene must then give); an absolute one may
name a field the scene leaves at its default. A field whose scene value is an integer gets
each sample rounded to the nearest integer.

A sample is the scene's parsed TOML with the varied fields replaced, parsed again by
:func:`hil_sim.scene.parse_scene`, so every field's own validation applies to every sample (a
sample outside a field's range is that sample's one-line error, not the sweep's end).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass
from pathlib import Path

from ecam.errors import InputError
from ecam.sampling import DISTRIBUTION_FIELDS, DISTRIBUTIONS, MAX_SAMPLES, METHODS, Distribution
from ecam.validate import Fields, show
from hil_sim.effects import FIDELITIES
from hil_sim.scene import MAX_MASTER_SPEED, MIN_MASTER_SPEED, Scene, parse_scene

#: How each sample is tuned.
TUNINGS = ("per_sample", "nominal")
#: The fields of ``[sweep]``.
SWEEP_FIELDS = ("samples", "seed", "method", "speeds", "speeds_rpm", "required_yield",
                "confidence", "tuning", "fidelity", "vary")
#: Most speeds one sweep may judge at.
MAX_SPEEDS = 100
#: Most fields one sweep may vary (each is checked by parsing the scene once).
MAX_FIELDS = 100
_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d{1,6})\])?$")


@dataclass(frozen=True)
class SweepSpec:
    """A scene's ``[sweep]`` table (see the module docstring).

    Attributes
    ----------
    samples, seed : int
    method : str
        One of :data:`ecam.sampling.METHODS`.
    speeds : tuple of float or None
        Master speeds to judge at [master units/s]; None with ``speeds_rpm`` or for the
        scene's own speed.
    speeds_rpm : tuple of float or None
        The same in master periods per minute.
    required_yield, confidence : float
        In (0, 1].
    tuning : {"per_sample", "nominal"}
    fidelity : {"auto", "full", "ideal"}
    vary : tuple of (str, Distribution)
        Dotted field name and its distribution, in the file's order.
    """

    vary: tuple[tuple[str, Distribution], ...]
    samples: int = 100
    seed: int = 0
    method: str = METHODS[0]
    speeds: tuple[float, ...] | None = None
    speeds_rpm: tuple[float, ...] | None = None
    required_yield: float = 0.95
    confidence: float = 0.95
    tuning: str = "per_sample"
    fidelity: str = "full"

    @property
    def distributions(self) -> dict:
        """{dotted name: Distribution}, in order."""
        return dict(self.vary)

    def speeds_per_second(self, scene: Scene, master_period: float) -> tuple[float, ...]:
        """The judged speeds [master units/s] (the scene's own when none are given)."""
        if self.speeds is not None:
            return self.speeds
        if self.speeds_rpm is not None:
            return tuple(rpm * master_period / 60.0 for rpm in self.speeds_rpm)
        return (scene.master.units_per_second(master_period),)

    def to_dict(self) -> dict:
        """The table as plain data (for the sweep's results and its fingerprint)."""
        return {"samples": self.samples, "seed": self.seed, "method": self.method,
                "speeds": None if self.speeds is None else list(self.speeds),
                "speeds_rpm": None if self.speeds_rpm is None else list(self.speeds_rpm),
                "required_yield": self.required_yield, "confidence": self.confidence,
                "tuning": self.tuning, "fidelity": self.fidelity,
                "vary": {name: d.to_dict() for name, d in self.vary}}


def parse_sweep(data: dict, base: Path = Path("."), source: str = "<scene>") -> SweepSpec:
    """The ``[sweep]`` table of a parsed scene, checked (its varied fields included: each must
    name a numeric field of the scene, tried at the distribution's median).

    Parameters
    ----------
    data : dict
        The whole scene as ``tomllib`` parses it.
    base : Path
        The scene file's directory (the cam file is resolved against it).
    source : str
        The scene's name in messages.

    Raises
    ------
    CamFileError
        No ``[sweep]`` table, an unknown field, a bad distribution, or a varied field the scene
        does not have; one line naming the field, the value and what was expected.
    """
    top = Fields(data, "", f"scene {source}")
    if "sweep" not in data:
        raise top.error("sweep: missing; expected a [sweep] table with [sweep.vary] "
                        "(see docs/sweep.md)")
    raw = top.table("sweep", SWEEP_FIELDS)
    if "speeds" in raw and "speeds_rpm" in raw:
        raise raw.error("sweep: give at most one of speeds (master units/s) and speeds_rpm "
                        "(master periods per minute)")
    vary_raw = raw.table("vary", required=True)
    if not vary_raw.raw:
        raise raw.error(f"{vary_raw.where}: {{}} should map at least one scene field to a "
                        "distribution")
    if len(vary_raw.raw) > MAX_FIELDS:
        raise raw.error(f"{vary_raw.where}: {len(vary_raw.raw)} fields should be at most "
                        f"{MAX_FIELDS}")
    vary = tuple((str(name), _distribution(vary_raw, name)) for name in vary_raw.raw)
    method = raw.choice("method", METHODS, default=METHODS[0])
    if method == "grid" and len(vary) > 2:
        raise raw.error(f"{raw.name('method')}: 'grid' should vary one or two fields, not "
                        f"{len(vary)} (use latin_hypercube)")
    required_yield = raw.number("required_yield", default=0.95, minimum=0.0, strict=True,
                                maximum=1.0)
    confidence = raw.number("confidence", default=0.95, minimum=0.0, strict=True, maximum=0.999999)
    spec = SweepSpec(
        vary=vary, samples=raw.integer("samples", default=100, minimum=1, maximum=MAX_SAMPLES),
        seed=raw.integer("seed", default=0, minimum=0, maximum=2**63 - 1), method=method,
        speeds=_speeds(raw, "speeds"), speeds_rpm=_speeds(raw, "speeds_rpm"),
        required_yield=required_yield, confidence=confidence,
        tuning=raw.choice("tuning", TUNINGS, default="per_sample"),
        fidelity=raw.choice("fidelity", FIDELITIES, default="full"))
    for name, distribution in vary:
        _check_field(data, name, distribution, base, source, vary_raw)
    return spec


def _speeds(raw: Fields, key: str) -> tuple[float, ...] | None:
    if key not in raw:
        return None
    value = raw.get(key)
    name = raw.name(key)
    if (not isinstance(value, list) or not 1 <= len(value) <= MAX_SPEEDS
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise raw.error(f"{name}: {show(value)} should be a list of 1..{MAX_SPEEDS} numbers")
    for v in value:
        if not (math.isfinite(v) and MIN_MASTER_SPEED <= abs(v) <= MAX_MASTER_SPEED):
            raise raw.error(f"{name}: {show(v)} should be a speed of magnitude in "
                            f"{MIN_MASTER_SPEED:g}..{MAX_MASTER_SPEED:g}")
    if len(set(value)) != len(value):
        raise raw.error(f"{name}: {show(value)} should not repeat a speed")
    return tuple(float(v) for v in value)


def _distribution(vary: Fields, name) -> Distribution:
    where = f'{vary.where}."{name}"' if isinstance(name, str) and len(name) < 60 else vary.name(show(name))
    table = vary.get(name)
    if not isinstance(table, dict):
        raise vary.error(f"{where}: {show(table)} should be a table such as {{ distribution = "
                         "\"normal\", mean = 1.0, std = 0.1, relative = true }")
    fields = Fields(table, where, vary.source, DISTRIBUTION_FIELDS)
    kind = fields.choice("distribution", tuple(DISTRIBUTIONS), required=True)
    with fields.calling():
        return Distribution(kind, **{k: v for k, v in table.items() if k != "distribution"})


def split_name(name: str) -> list[str | int]:
    """``"axis[1].mechanics.load_inertia"`` -> ``["axis", 1, "mechanics", "load_inertia"]``.

    Raises
    ------
    InputError
        A name that is not dotted words with optional ``[index]``.
    """
    if not isinstance(name, str) or not name or len(name) > 200:
        raise InputError(f"{show(name)}: should be a dotted scene field name such as "
                         "mechanics.coupling_stiffness")
    path: list[str | int] = []
    for part in name.split("."):
        match = _PART.match(part)
        if match is None:
            raise InputError(f"{show(name)}: should be a dotted scene field name such as "
                             "mechanics.coupling_stiffness (words, [index] for an array)")
        path.append(match.group(1))
        if match.group(2) is not None:
            path.append(int(match.group(2)))
    return path


def _walk(data, path, create: bool):
    """The container holding the last key of ``path``; tables on the way are created when
    ``create`` (a field the scene leaves at its default may sit in a table it does not have)."""
    node = data
    for i, key in enumerate(path[:-1]):
        if isinstance(key, int):
            if not isinstance(node, list) or key >= len(node):
                raise KeyError(".".join(map(str, path[:i + 1])))
            node = node[key]
            continue
        if not isinstance(node, dict):
            raise KeyError(key)
        if key not in node:
            if not create or isinstance(path[i + 1], int):
                raise KeyError(key)
            node[key] = {}
        node = node[key]
    if not isinstance(node, (dict, list)):
        raise KeyError(path[-1])
    return node


def nominal_value(data: dict, name: str) -> float | int | None:
    """The scene's own value of the dotted field ``name`` (None when the scene does not give
    it); raises InputError when the name is malformed or names a value that is not a number."""
    path = split_name(name)
    try:
        node = _walk(data, path, create=False)
        value = node[path[-1]]
    except (KeyError, IndexError, TypeError):
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{name}: {show(value)} is not a number in the scene, so it cannot "
                         "be varied")
    return value


def sample_data(data: dict, values: dict) -> dict:
    """A copy of the scene's mapping with the dotted fields set to ``values`` (rounded where
    the scene's value is an integer) and without its ``[sweep]`` table."""
    out = copy.deepcopy({k: v for k, v in data.items() if k != "sweep"})
    for name, value in values.items():
        path = split_name(name)
        node = _walk(out, path, create=True)
        current = node[path[-1]] if isinstance(node, dict) and path[-1] in node else None
        if isinstance(current, int) and not isinstance(current, bool):
            value = int(round(value))
        node[path[-1]] = value
    return out


def _check_field(data: dict, name: str, distribution: Distribution, base: Path, source: str,
                 vary: Fields) -> None:
    """``name`` must be a numeric field of the scene: tried at the distribution's median."""
    where = f'{vary.where}."{name}"'
    try:
        nominal = nominal_value(data, name)
    except InputError as exc:
        raise vary.error(f"{where}: {exc}") from None
    if distribution.relative and nominal is None:
        raise vary.error(f"{where}: relative, but the scene does not give {name}; give it in "
                         "the scene or use absolute values (relative = false)")
    median = float(distribution.quantile([0.5], nominal)[0])
    try:
        parse_scene(sample_data(data, {name: median}), base=base, source=source)
    except KeyError:
        raise vary.error(f"{where}: no such field in the scene") from None
    except InputError as exc:
        raise vary.error(f"{where}: the scene with its median {median:.6g} does not read: "
                         f"{str(exc).removeprefix(f'scene {source}: ')}") from None
