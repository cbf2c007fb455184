"""Which effects a run models: all (``"full"``), none (``"ideal"``), or, by default
(``"auto"``), every effect measured to matter.

``auto`` measures on the bus-free path (:mod:`hil_sim.rig.fast`): the scene with every effect
on (the full model), then once more without each effect in turn. An effect stays in when leaving
it out moves any check by more than :data:`SHARE` of that check's limit, or flips a check's
verdict. Then the reduced model is run and compared with the full one check by check; while a
check still differs by more than :data:`SHARE` of its limit or in its verdict, the effect left
out that moved the checks most goes back in; and while a check's value (an information line's
too) lies more than :data:`RELATIVE` of the full model's value from it, the effect left out that
moved that check most goes back in (issue 10: the default run gives the full model's verdicts
and every check's value within 10 % of it; an effect that moves a small value by a large share
of itself can stay under 2 % of the limit). The report lists every effect: in or out, why, and
the change it measured; and how far the reduced model's checks lie from the full model's.

The checks compared are the physical ones with a limit (following and tracking error, coupling
torques, wind-up when it has a limit, torque saturation, faults); bus load does not depend on
the plant, and a check without a limit has no verdict to move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hil_sim.effects import EFFECTS, EffectValues, describe
from hil_sim.plant import choose_model
from hil_sim.report import Check

#: An effect whose absence moves a check by more than this share of its limit is modelled.
SHARE = 0.02
#: The reduced model's every check value lies within this share of the full model's.
RELATIVE = 0.10
#: The step of a check whose values are whole numbers (counts, faults): a difference of one step
#: is the value's own resolution, not the model's (1 count against 3 is no 10 % to hold).
_STEP = {"following_error": 1.0, "faults": 1.0}
_NOT_PHYSICAL = ("bus_load", "resonance_excitation")


@dataclass(frozen=True)
class EffectChoice:
    """One effect in the report.

    Attributes
    ----------
    name : str
    included : bool
        Whether the run modelled it.
    value : str
        Its value in its unit ("n/a" where it does not apply).
    source : str
        ``"scene"`` or the default's rule.
    why : str
        Why it is in or out.
    change : float or None
        Measured: the largest change of a check, as a share of its limit, when the effect is left
        out of the full model (None: not measured).
    check : str or None
        The check that moved most.
    """

    name: str
    included: bool
    value: str
    source: str
    why: str
    change: float | None = None
    check: str | None = None

    def to_dict(self) -> dict:
        return {"name": self.name, "included": self.included, "value": self.value,
                "source": self.source, "why": self.why, "change": self.change,
                "check": self.check}


@dataclass(frozen=True)
class Selection:
    """The effects a run models, and the report's account of them.

    Attributes
    ----------
    fidelity : str
    included : frozenset of str
    choices : tuple of EffectChoice
        Every effect, in :data:`hil_sim.effects.EFFECTS` order.
    proof : dict or None
        ``auto``: ``runs`` (bus-free runs made), ``largest_difference`` (share of a limit) and
        ``check`` where the reduced model's checks differ most from the full model's,
        ``same_verdicts``; ``largest_relative`` (share of the full value) and
        ``relative_check`` where a check's value lies furthest from the full model's, and
        ``within_relative`` (every value within :data:`RELATIVE` of it, or one step).
    """

    fidelity: str
    included: frozenset
    choices: tuple
    proof: dict | None = None

    def to_dict(self) -> dict:
        return {"fidelity": self.fidelity, "effects": [c.to_dict() for c in self.choices],
                "proof": self.proof}


#: A limit of 0 (no torque saturation, no fault allowed) is measured in these steps instead.
_ZERO_LIMIT_SCALE = {"motor_saturation": 1.0, "faults": 1.0}  # one percent point, one fault


def _scale(check: Check) -> float:
    """What a check's change is measured against: its limit (for a limit of 0, one step of its
    unit: a percent point of saturation, one fault)."""
    return abs(check.limit) if check.limit else _ZERO_LIMIT_SCALE.get(check.name, 1.0)


def compare(full: list[Check], other: list[Check]) -> tuple[float, Check | None, str | None]:
    """(largest change as a share of the limit, that check (its full-model line), the first
    check whose verdict differs or None) of ``other`` against ``full``; the physical checks with
    a limit only."""
    worst, where, flipped = 0.0, None, None
    for a, b in zip(full, other):
        if a.name in _NOT_PHYSICAL or a.limit is None:
            continue
        if a.passed != b.passed and flipped is None:
            flipped = a.name
        if a.value is None or b.value is None:
            change = 0.0 if a.value is b.value else math.inf
        else:
            change = abs(a.value - b.value) / _scale(a)
        if change > worst:
            worst, where = change, a
    return worst, where, flipped


def relative(full: list[Check], other: list[Check]) -> tuple[float, float, Check | None]:
    """How far ``other``'s check values lie from ``full``'s, every check with a value: (largest
    ratio of the difference to what is allowed, max(:data:`RELATIVE` x the full value, the
    check's step); that difference as a share of the full value; that check (its full-model
    line)). A ratio above 1 is a value outside the proof."""
    worst, share, where = 0.0, 0.0, None
    for a, b in zip(full, other):
        if a.value is None or b.value is None:
            excess = 0.0 if a.value is b.value else math.inf
            part = excess
        else:
            difference = abs(a.value - b.value)
            allowed = max(RELATIVE * abs(a.value), _STEP.get(a.name, 0.0))
            excess = difference / allowed if allowed > 0.0 else (math.inf if difference else 0.0)
            part = difference / abs(a.value) if a.value else (math.inf if difference else 0.0)
        if excess > worst:
            worst, share, where = excess, part, a
    return worst, share, where


def select(fidelity: str, values: EffectValues, forced_model: str | None,
           measure=None, rule=None) -> Selection:
    """The effects of a run.

    Parameters
    ----------
    fidelity : {"auto", "full", "ideal"}
    values : EffectValues
        Every effect's value for the scene.
    forced_model : {"rigid", "two_mass"} or None
        The scene's ``drive.model`` when it is not ``"auto"``: the coupling's compliance is then
        the scene's choice, not measured.
    measure : callable, optional
        ``measure(included) -> list of Check`` on the bus-free path (needed for ``"auto"``).
    rule : tuple of (mechanics, excitation_hz, loop_bandwidth_hz), optional
        For ``"ideal"``: :func:`hil_sim.plant.choose_model`'s arguments.
    """
    applicable = values.applicable
    fixed = {}
    if forced_model is not None and "torsional_compliance" in applicable:
        fixed["torsional_compliance"] = forced_model == "two_mass"
    choices = {}
    if fidelity == "full":
        included = {name for name in applicable if fixed.get(name, True)}
        for name in applicable:
            choices[name] = "fidelity full: every effect" if name in included else \
                f"drive.model = {forced_model!r}"
        return _selection(fidelity, values, included, choices)
    if fidelity == "ideal":
        included = set()
        if "torsional_compliance" in applicable:
            keep = fixed.get("torsional_compliance")
            reason = f"drive.model = {forced_model!r}"
            if keep is None:
                kind, reason = choose_model(*rule)
                keep = kind == "two_mass"
            if keep:
                included.add("torsional_compliance")
            choices["torsional_compliance"] = reason
        for name in applicable:
            choices.setdefault(name, "fidelity ideal: left out")
        return _selection(fidelity, values, included, choices)
    return _measured(values, applicable, fixed, forced_model, measure)


def _measured(values, applicable, fixed, forced_model, measure) -> Selection:
    """``auto``: measure each effect against the full model (module docstring)."""
    full_set = frozenset(name for name in applicable if fixed.get(name, True))
    full = measure(full_set)
    runs = 1
    changes = {}
    left_out = {}  # each effect's run without it: its checks
    included = set()
    choices = {}
    for name in applicable:
        if name in fixed:
            if fixed[name]:
                included.add(name)
            choices[name] = f"drive.model = {forced_model!r}"
            continue
        without = measure(full_set - _with_dependents(name))
        left_out[name] = without
        runs += 1
        change, check, flipped = compare(full, without)
        changes[name] = (change, None if check is None else check.name)
        if change > SHARE or flipped:
            included.add(name)
            flip = f", and flips the verdict of {flipped}" if flipped else ""
            choices[name] = f"leaving it out moves {_by(check, change)}{flip}"
        else:
            choices[name] = (f"leaving it out moves no check by more than "
                             f"{100 * change:.2g} % of its limit (at most {100 * SHARE:g} %)")
    if ("gear_backlash" in included and "torsional_compliance" in changes
            and "torsional_compliance" not in included):
        included.add("torsional_compliance")  # the backlash sits in series with the spring
        choices["torsional_compliance"] = "the gear backlash needs it (in series with the spring)"
    reduced = measure(frozenset(included))
    runs += 1
    difference, where, flipped = compare(full, reduced)
    excess, share, off = relative(full, reduced)
    while (difference > SHARE or flipped or excess > 1.0) and changes.keys() - included:
        change_left = changes.keys() - included
        if difference > SHARE or flipped:
            # left out together, small effects may add up: put back the one that moved most
            name = max(change_left, key=lambda n: (changes[n][0], n))
            moved = _by(where, difference)
        else:
            # a value off the full model's by more than RELATIVE of itself: put back the effect
            # whose absence moved that check most
            index = full.index(off)
            name = max(change_left, key=lambda n: (_moved(full[index], left_out[n][index]), n))
            moved = (f"{off.name} by {100 * share:.3g} % of the full model's value "
                     f"(more than {100 * RELATIVE:g} %)")
        included.add(name)
        change, check = changes[name]
        choices[name] = (f"put back: the effects left out together moved {moved}"
                         f" (alone it moved {check} by {100 * change:.3g} % of its limit)")
        reduced = measure(frozenset(included))
        runs += 1
        difference, where, flipped = compare(full, reduced)
        excess, share, off = relative(full, reduced)
    proof = {"runs": runs, "largest_difference": difference,
             "check": None if where is None else where.name, "same_verdicts": flipped is None,
             "largest_relative": share if math.isfinite(share) else None,  # None: a value missing
             "relative_check": None if off is None else off.name,
             "within_relative": excess <= 1.0}
    return _selection("auto", values, included, choices, changes, proof)


def _moved(a: Check, b: Check) -> float:
    """How far a check's value moved between two runs (infinite when one has none)."""
    if a.value is None or b.value is None:
        return 0.0 if a.value is b.value else math.inf
    return abs(a.value - b.value)


def _by(check: Check, change: float) -> str:
    """"<check> by <amount>": a share of its limit, or for a limit of 0 its own unit."""
    if check.limit:
        return f"{check.name} by {100 * change:.3g} % of its limit (more than {100 * SHARE:g} %)"
    unit = "percent points" if check.unit == "%" else check.unit
    return f"{check.name} by {change * _scale(check):.3g} {unit} (its limit is 0)"


def _with_dependents(name: str) -> set:
    """The effects that go with ``name`` when it is left out: the backlash with the coupling's
    compliance (it sits in series with the spring: no spring, no backlash)."""
    return {name, "gear_backlash"} if name == "torsional_compliance" else {name}


def _selection(fidelity, values, included, reasons, changes=None, proof=None) -> Selection:
    changes = changes or {}
    out = []
    for effect in EFFECTS:
        value = values[effect.name]
        change, check = changes.get(effect.name, (None, None))
        why = reasons.get(effect.name) or value.source
        out.append(EffectChoice(effect.name, effect.name in included, describe(value),
                                value.source, why, change, check))
    return Selection(fidelity, frozenset(included), tuple(out), proof)
