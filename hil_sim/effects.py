"""The effects that can change a verdict, their values, and where typical values come from.

A scene describes a machine; some effects it may leave unsaid (a gearhead's backlash, the
friction of bearings and seals, the coupling's own inertia, the drive's encoder, current loop
and computation delay). Each one can move a check, so the rig knows a typical value for each
(:data:`EFFECTS`, with the rule and its source) and uses the scene's value where it gives one.
``fidelity = "full"`` runs all of them; ``"auto"`` (the default) measures each one's influence
and keeps those that matter (:mod:`hil_sim.rig.fidelity`); ``"ideal"`` runs none (the rigid or
two-mass model by rule, an ideal drive).

Sources of the defaults (catalogue figures, read from the vendors' published data):

* backlash: precision planetary servo gearheads are sold as "standard" <= 3 arcmin and "reduced"
  <= 1 arcmin (WITTENSTEIN alpha SP+/TP+ catalogues; Beckhoff AG2300 SP and AG2400 TP data
  sheets), economy units <= 8 arcmin;
* motor-side Coulomb friction: the gearhead's catalogue no-load (idle) torque at the input,
  T012, where the scene names a gearhead (``[mechanics] gearhead`` or
  ``gearhead_idle_torque``; WITTENSTEIN alpha SP+ 075 MF: 0.96 N m at i = 5, 0.52 N m at i = 10,
  Beckhoff AG2300 SP075 MF data sheet, measured at n1 = 3000 rpm, so taken as Coulomb friction
  it is on the safe side at lower speeds). Without a gearhead's data: a planetary gearhead's
  no-load torque at the input is 3-9 % of its rated output torque over the ratio (Beckhoff
  AG2300/AG2400 data sheets, T012), about half of it speed-independent, and a servo motor adds
  its own static friction (a datasheet field, Kollmorgen "Motor Data Legend": M_R); a servo's
  peak torque is 3-5 times its standstill torque (Siemens 1FT7044: 23 N m against 5 N m), so
  1 % of the drive's torque limit stands for both;
* load-side Coulomb friction: no catalogue gives a rule (rolling guides and bearings have
  friction coefficients of 0.002-0.01); the rig assumes 1 % of the torque the motor can put on
  the load shaft;
* coupling inertia: metal bellows couplings (RINGFEDER GWB AKN/AKD/AK tech papers, 22 to
  5000 N m) fit J = 5.4e-7 T_KN^1.48 kg m^2 for their rated torque T_KN in N m, within a factor
  2.5; without a rated torque, T_KN = C_T / 1000 (C_T about 1000 T_KN per rad for stiff bellows);
* encoder: 2^20 counts per revolution (Beckhoff AX5000 S-0-0079 default, OCT feedback 20
  bits; Yaskawa Sigma-7 24 bits, Siemens 22 bits are finer), the speed estimate filtered at a
  quarter of the controller rate (Moog DS2110: a first-order speed filter at 0.25 f_s);
* current loop: a torque loop -3 dB at 650-900 Hz (Siemens SINAMICS S120 with 1FK7/1FT7 motors,
  125 us controller cycle); 1 kHz;
* computation delay: the torque computed from one controller period's samples is applied in
  the next (sample, compute, then write the PWM): one controller period.
"""

from __future__ import annotations

from dataclasses import dataclass

from ecam import validate
from ecam.mechanics import Mechanics
from hil_sim.control import DriveEffects
from hil_sim.plant import ARCMIN, MechanicalEffects

#: How much of the effects a run models (a scene's ``fidelity``).
FIDELITIES = ("auto", "full", "ideal")

DEFAULT_BACKLASH_ARCMIN = 3.0
DEFAULT_MOTOR_FRICTION_SHARE = 0.01  # of the motor torque limit
DEFAULT_LOAD_FRICTION_SHARE = 0.01  # of the torque the motor can put on the load shaft
COUPLING_INERTIA_FIT = (5.4e-7, 1.48)  # J = a T_KN^b [kg m^2], T_KN in N m
COUPLING_STIFFNESS_PER_TORQUE = 1000.0  # C_T / T_KN of stiff metal bellows [1/rad]
DEFAULT_ENCODER_COUNTS = 2**20
VELOCITY_FILTER_SHARE = 0.25  # of the controller rate
DEFAULT_CURRENT_LOOP_HZ = 1000.0

#: The scene fields of the effects: [mechanics] and [drive] keys.
MECHANICS_FIELDS = ("gear_backlash", "motor_coulomb_friction", "load_coulomb_friction",
                    "coupling_inertia")
DRIVE_FIELDS = ("encoder_counts_per_rev", "velocity_filter_hz", "current_loop_bandwidth_hz",
                "computation_delay")


@dataclass(frozen=True)
class Effect:
    """One effect as the report names it.

    Attributes
    ----------
    name : str
        Stable identifier (``"gear_backlash"``).
    what : str
        What it is, for people.
    unit : str
    """

    name: str
    what: str
    unit: str


#: Every effect the rig knows, in the report's order.
EFFECTS = (
    Effect("torsional_compliance", "the coupling's twist (two-mass model instead of rigid)", "N m/rad"),
    Effect("gear_backlash", "gear backlash at the load shaft", "rad"),
    Effect("motor_coulomb_friction", "Coulomb friction at the motor shaft", "N m"),
    Effect("load_coulomb_friction", "Coulomb friction at the load shaft", "N m"),
    Effect("coupling_inertia", "the coupling's own inertia, half to each side", "kg m^2"),
    Effect("encoder", "encoder resolution and the speed estimated from it", "counts/rev"),
    Effect("current_loop", "the current loop's lag of the torque", "Hz"),
    Effect("computation_delay", "one controller period of computation delay", "periods"),
)
EFFECT_NAMES = tuple(e.name for e in EFFECTS)


@dataclass(frozen=True)
class EffectValue:
    """An effect's value for a scene and where it came from.

    Attributes
    ----------
    name : str
    value : float or None
        What the full model runs with (None: the effect does not apply to this machine).
    source : str
        ``"scene"``, or the default's rule with its numbers, or why it does not apply.
    """

    name: str
    value: float | None
    source: str

    @property
    def applies(self) -> bool:
        """True when the full model has this effect (a value that is not None or zero)."""
        return self.value is not None and self.value != 0


@dataclass(frozen=True)
class EffectValues:
    """Every effect's value for one scene (:func:`resolve`), and what to build from a subset."""

    values: tuple[EffectValue, ...]
    velocity_filter_hz: float

    def __getitem__(self, name: str) -> EffectValue:
        for value in self.values:
            if value.name == name:
                return value
        raise KeyError(name)

    @property
    def applicable(self) -> tuple[str, ...]:
        """The effects the full model has, in the report's order."""
        return tuple(v.name for v in self.values if v.applies)

    def build(self, included) -> tuple[str, MechanicalEffects, DriveEffects]:
        """(model, plant effects, drive effects) of a run with the ``included`` effects on.

        The model is ``"two_mass"`` when the coupling's compliance (or the backlash, which
        sits in series with it) is included, else ``"rigid"``.
        """
        on = {name: self[name].value for name in included if self[name].applies}
        plant = MechanicalEffects(
            gear_backlash=on.get("gear_backlash", 0.0),
            motor_coulomb_friction=on.get("motor_coulomb_friction", 0.0),
            load_coulomb_friction=on.get("load_coulomb_friction", 0.0),
            coupling_inertia=on.get("coupling_inertia", 0.0))
        encoder = on.get("encoder")
        drive = DriveEffects(
            encoder_counts_per_rev=None if encoder is None else int(encoder),
            velocity_filter_hz=self.velocity_filter_hz,
            current_loop_hz=on.get("current_loop"),
            computation_delay="computation_delay" in on)
        two_mass = "torsional_compliance" in on or "gear_backlash" in on
        return ("two_mass" if two_mass else "rigid"), plant, drive


def resolve(mechanics: Mechanics, given_mechanics: dict, given_drive: dict,
            control_rate_hz: float, gearhead_idle_torque: float | None = None) -> EffectValues:
    """Each effect's value for a machine: the scene's where it gives one, else the default.

    Parameters
    ----------
    mechanics : Mechanics
        The machine (the defaults scale with it).
    given_mechanics : dict
        The effect fields the scene's ``[mechanics]`` gives (``gear_backlash`` ...).
    given_drive : dict
        The effect fields the scene's ``[drive]`` gives (``encoder_counts_per_rev``,
        ``velocity_filter_hz``, ``current_loop_bandwidth_hz``, ``computation_delay``).
    control_rate_hz : float
        The drive's controller rate [Hz] (the speed filter's default scales with it).
    gearhead_idle_torque : float, optional
        The gearhead's catalogue no-load torque T012 at its input [N m]: the motor-side
        friction's default when given.

    Returns
    -------
    EffectValues
    """
    m = mechanics
    coupling = m.coupling_stiffness is not None
    values = []

    def add(name: str, value, source: str) -> None:
        values.append(EffectValue(name, value, source))

    def given(fields: dict, key: str, default, rule: str, unit: str = ""):
        if key in fields:
            return fields[key], "scene"
        return default, f"default: {rule}" + (f" = {default:.4g} {unit}" if unit else "")

    if coupling:
        add("torsional_compliance", m.coupling_stiffness, "scene")
    else:
        add("torsional_compliance", None, "not applicable: no coupling_stiffness (a rigid axis)")

    if not coupling:
        add("gear_backlash", None, "not applicable: no coupling_stiffness (backlash sits in "
                                   "series with the coupling spring)")
    else:
        geared = m.gear_ratio != 1.0
        default = DEFAULT_BACKLASH_ARCMIN * ARCMIN if geared else 0.0
        rule = (f"{DEFAULT_BACKLASH_ARCMIN:g} arcmin, a standard-class precision planetary "
                f"gearhead" if geared else "none without a gear (gear_ratio 1)")
        add("gear_backlash", *given(given_mechanics, "gear_backlash", default, rule,
                                    "rad" if geared else ""))

    limit = m.motor_torque_limit
    if gearhead_idle_torque is not None:
        add("motor_coulomb_friction", *given(
            given_mechanics, "motor_coulomb_friction", gearhead_idle_torque,
            "the gearhead's catalogue no-load torque T012 at its input", "N m"))
    else:
        motor_default = DEFAULT_MOTOR_FRICTION_SHARE * limit if limit else 0.0
        add("motor_coulomb_friction", *given(
            given_mechanics, "motor_coulomb_friction", motor_default,
            "1 % of motor_torque_limit (gearhead no-load torque and motor friction)" if limit
            else "none (no motor_torque_limit to scale it by)", "N m" if limit else ""))

    load_scale = limit * m.gear_efficiency / m.gear_ratio if limit else 0.0
    add("load_coulomb_friction", *given(
        given_mechanics, "load_coulomb_friction", DEFAULT_LOAD_FRICTION_SHARE * load_scale,
        "1 % of the torque the motor can put on the load shaft (an assumption)" if limit else
        "none (no motor_torque_limit to scale it by)", "N m" if limit else ""))

    if not coupling:
        add("coupling_inertia", None, "not applicable: no coupling")
    else:
        rated = m.coupling_rated_torque
        basis = rated if rated is not None else m.coupling_stiffness / COUPLING_STIFFNESS_PER_TORQUE
        a, b = COUPLING_INERTIA_FIT
        default = a * basis**b
        rule = (f"metal bellows of rated torque {basis:.4g} N m"
                + ("" if rated is not None else " (from the stiffness)")
                + f", J = {a:g} T^{b:g}")
        add("coupling_inertia", *given(given_mechanics, "coupling_inertia", default, rule,
                                       "kg m^2"))

    add("encoder", *given(given_drive, "encoder_counts_per_rev", DEFAULT_ENCODER_COUNTS,
                          "a 20-bit encoder", "counts/rev"))
    filter_hz = given_drive.get("velocity_filter_hz", VELOCITY_FILTER_SHARE * control_rate_hz)
    add("current_loop", *given(given_drive, "current_loop_bandwidth_hz", DEFAULT_CURRENT_LOOP_HZ,
                               "a torque loop of 1 kHz bandwidth", "Hz"))
    delay, source = given(given_drive, "computation_delay", True, "one controller period")
    add("computation_delay", 1.0 if delay else 0.0, source)
    return EffectValues(tuple(values), validate.positive("velocity_filter_hz", filter_hz))


def describe(value: EffectValue) -> str:
    """The value in its unit, for the report (backlash also in arcmin)."""
    if value.value is None:
        return "n/a"
    if value.name == "gear_backlash":
        return f"{value.value:.4g} rad ({value.value / ARCMIN:.3g} arcmin)"
    if value.name == "computation_delay":
        return "one controller period" if value.value else "none"
    unit = next(e.unit for e in EFFECTS if e.name == value.name)
    return f"{value.value:.4g} {unit}"
