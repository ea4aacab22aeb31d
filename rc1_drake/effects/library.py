"""The library: every effect by name (register adds a user's own), the candidate groups, and what a scenario's
`effects:` mapping makes of the model, the gait and the sensors."""

import math

import numpy as np

from ..config import GRAVITY_M_S2, NUM_JOINTS, Gait, Rc1Error, Servo
from ..discrepancy import term_names
from .base import Effect, EffectParameter, ModelSetup, SensorModel
from .physical import (
    CompliantStop,
    GroundSlope,
    HeadCantilever,
    HeadDrag,
    JointCoulombFriction,
    LateralFrictionAsymmetry,
    LongitudinalFrictionAsymmetry,
    ModulePayload,
    ServoLag,
    ServoLinkage,
    StribeckFriction,
    TailTether,
    WheelToe,
)
from .sensors import CameraDelay, ImuFault, PotentiometerFault, PotentiometerGain, PotentiometerOffset
from .terms import DiscrepancyTerm

LIBRARY: dict[str, Effect] = {}


def register(effect: Effect) -> Effect:
    """Add an effect to the library (a user's own, for instance); its parameter keys must be new."""
    taken = {p.key for e in LIBRARY.values() for p in e.parameters if e.name != effect.name}
    for p in effect.parameters:
        if p.key in taken:
            raise ValueError(f"effect {effect.name}: parameter key {p.key} is already used")
    LIBRARY[effect.name] = effect
    return effect


for _effect in (
    GroundSlope(),
    LateralFrictionAsymmetry(),
    LongitudinalFrictionAsymmetry(),
    HeadDrag(),
    JointCoulombFriction(),
    CompliantStop(),
    HeadCantilever(),
    TailTether(),
    StribeckFriction(),
    WheelToe(),
    ModulePayload(),
    ServoLag(),
    ServoLinkage(),
    *(PotentiometerOffset(j) for j in range(1, NUM_JOINTS + 1)),
    *(PotentiometerGain(j) for j in range(1, NUM_JOINTS + 1)),
    CameraDelay(),
    ImuFault(),
    *(DiscrepancyTerm(i, *term) for i, term in enumerate(term_names())),
):
    register(_effect)


# Names that stand for a group of the library in a list of candidates (diagnose, rc1 diagnose --candidates).
CANDIDATE_GROUPS = {
    "physical": lambda e: not e.sensor and e.default_candidate,
    "sensor": lambda e: e.sensor,
    "study": lambda e: not e.default_candidate and not e.discrepancy,  # issue 41's mechanisms (docs/paper.md)
    "discrepancy": lambda e: e.discrepancy,  # the discrepancy model's terms (discrepancy.py), for discovery
}


def candidate_names(names: list[str] | None = None) -> list[str]:
    """Effect names, with the groups expanded; by default the physical effects. The sensor faults are asked for
    (`sensor`): from the motion alone a bend at one joint mimics a toe or a failed joint's dry friction
    (docs/findings.md), so on by default they would blur what the physics tells."""
    out = []
    for name in names or ["physical"]:
        if name in CANDIDATE_GROUPS:
            out += [e.name for e in LIBRARY.values() if CANDIDATE_GROUPS[name](e)]
        elif name in LIBRARY:
            out.append(name)
        else:
            raise ValueError(
                f"unknown effect '{name}' (known: {', '.join(LIBRARY)}; groups: {', '.join(CANDIDATE_GROUPS)})"
            )
    return list(dict.fromkeys(out))


def potentiometer_faults(joints) -> list[str]:
    """The sensor-fault candidates of these joints' potentiometers (1-based joint numbers)."""
    return [e.name for e in LIBRARY.values() if isinstance(e, PotentiometerFault) and e.joint in set(joints)]


def parameter_owner(key: str) -> Effect | None:
    return next((e for e in LIBRARY.values() if any(p.key == key for p in e.parameters)), None)


def parameter(key: str) -> EffectParameter | None:
    """The effect parameter with this key, or None."""
    return next((p for e in LIBRARY.values() for p in e.parameters if p.key == key), None)


def effect_values(effects: dict[str, float], effect: Effect) -> dict[str, float]:
    return {p.key: float(effects.get(p.key, p.default)) for p in effect.parameters}


def active(effects: dict[str, float]) -> list[Effect]:
    """The effects whose parameters `effects` sets (in library order)."""
    return [e for e in LIBRARY.values() if any(p.key in effects for p in e.parameters)]


def validate_effects(effects: dict[str, float], *, where: str) -> None:
    """Rc1Error naming the first unknown key or out-of-range value."""
    for key, value in effects.items():
        p = parameter(key)
        if p is None:
            known = ", ".join(p.key for e in LIBRARY.values() for p in e.parameters)
            raise Rc1Error(f"{where}: effects.{key}: unknown effect parameter (known: {known})")
        if value is None or not math.isfinite(value) or not p.lower <= value <= p.upper:
            raise Rc1Error(f"{where}: effects.{key}: must be a number in [{p.lower:g}, {p.upper:g}], got {value}")


def parse_effect(text: str) -> tuple:
    """`NAME=VALUE` (an effect's main parameter) or `KEY=VALUE` (any parameter) -> (key, value)."""
    name, sep, value = text.partition("=")
    effect = LIBRARY.get(name)
    key = effect.main.key if effect is not None else name
    if parameter(key) is None:
        raise ValueError(f"unknown effect '{name}' (known: {', '.join(LIBRARY)}, or a parameter key)")
    if not sep:
        raise ValueError(f"effect '{name}' needs a value: {name}=VALUE")
    try:
        return key, float(value)
    except ValueError:
        raise ValueError(f"effect '{name}': '{value}' is not a number") from None


def coordinate_owner(name: str) -> Effect | None:
    """The effect with a fitted parameter or a diagnosis coordinate called `name`, or None."""
    return next((e for e in LIBRARY.values() if any(p.key == name for p in (*e.fitted(), *e.coordinate_space()))), None)


def shifted(effects: dict[str, float], name: str, delta: float) -> dict[str, float]:
    """`effects` with the fitted parameter or coordinate `name` (coordinate_owner) moved by `delta`."""
    effect = coordinate_owner(name)
    if effect is None:
        raise ValueError(f"no effect parameter or coordinate '{name}'")
    values = effect_values(effects, effect)
    if name in values:
        return {**effects, name: values[name] + delta}
    coordinates = effect.coordinates(values)
    coordinates[name] += delta
    return {**effects, **effect.from_coordinates(coordinates)}


def commanded_gait(gait: Gait, effects: dict[str, float]) -> Gait:
    """The gait as the joints receive it, after the effects that act on the command (servo_lag)."""
    for effect in active(effects):
        gait = effect.gait(gait, effect_values(effects, effect))
    return gait


def running_servo(servo: Servo, effects: dict[str, float]) -> Servo:
    """The servo as the joints feel it, after the effects between servo and joint (servo_linkage); what both
    engines run."""
    for effect in active(effects):
        servo = effect.servo(servo, effect_values(effects, effect))
    return servo


def sensor_model(effects: dict[str, float]) -> SensorModel:
    """The sensors as the active sensor faults make them."""
    sensors = SensorModel(angle_offsets_rad=np.zeros(NUM_JOINTS))
    for effect in active(effects):
        effect.configure_sensors(sensors, effect_values(effects, effect))
    return sensors


def model_setup(effects: dict[str, float]) -> ModelSetup:
    setup = ModelSetup(gravity=np.array([0.0, 0.0, -GRAVITY_M_S2]))
    for effect in active(effects):
        effect.configure(setup, effect_values(effects, effect))
    return setup


def apply_effects(built, context, effects: dict[str, float], *, friction, sgn_smoothing_m_s: float) -> ModelSetup:
    """Write the friction and the effects into `context` (after SetDefaultContext): gravity, payload, the
    friction parameters (friction.friction_parameters: coefficients, friction-law terms, normal forces,
    wheel toe), explicit forces. Every run calls it, so nothing of a previous run's effects stays."""
    from ..friction import KnownForces, friction_parameters
    from ..model import set_payload

    setup = model_setup(effects)
    plant, system = built.plant, built.friction
    plant.mutable_gravity_field().set_gravity_vector(setup.gravity)  # the plant's, shared by its contexts
    set_payload(plant, plant.GetMyMutableContextFromRoot(context), setup.payload_module, setup.payload_kg)
    system.parameters(system.GetMyMutableContextFromRoot(context))[:] = friction_parameters(
        friction=friction, sgn_smoothing_m_s=sgn_smoothing_m_s, setup=setup, geometry=built.rc1.geometry
    )
    known = KnownForces(tuple(setup.extra_forces), bool(setup.gravity[0] or setup.gravity[1]))
    system.set_known_forces(system.GetMyMutableContextFromRoot(context), known)
    return setup
