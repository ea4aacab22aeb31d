"""Candidate effects beyond the paper's model: a library that a run, a synthesized truth, a fit or a diagnosis
adds by name. Most are physical; the sensor faults (Effect.sensor) leave the robot alone and change what its
sensors report (SensorModel): the data a truth is measured into, and what a replay is compared with.

A scenario's `effects:` mapping holds parameter values by key (`ground_slope_deg: 3.0`); a missing key
is 0 (or a setting's default), and every effect at 0 is the paper's model exactly (nested models).
Each effect is one small class: its parameters (bounds, and whether a fit estimates them or the user
sets them) and how it changes the model, by editing a ModelSetup (gravity, payload, friction-law
terms, wheel toe, explicit forces), for the commanded gait, the Gait, and for a sensor fault, the SensorModel.
`register()` adds a user's own; docs/effects.md shows one.

Sign conventions are the README's: world x toward the line, y left, z up; a wheel's +x rolls forward
(toward the head), +y is its left.
"""

from .base import Effect, EffectParameter, ModelSetup, SensorModel
from .library import (
    CANDIDATE_GROUPS,
    LIBRARY,
    active,
    apply_effects,
    candidate_names,
    commanded_gait,
    coordinate_owner,
    effect_values,
    model_setup,
    parameter,
    parameter_owner,
    parse_effect,
    potentiometer_faults,
    register,
    running_servo,
    sensor_model,
    shifted,
    validate_effects,
)
from .physical import stop_backstops

__all__ = [
    "CANDIDATE_GROUPS",
    "LIBRARY",
    "Effect",
    "EffectParameter",
    "ModelSetup",
    "SensorModel",
    "active",
    "apply_effects",
    "candidate_names",
    "commanded_gait",
    "coordinate_owner",
    "effect_values",
    "model_setup",
    "parameter",
    "parameter_owner",
    "parse_effect",
    "potentiometer_faults",
    "register",
    "running_servo",
    "sensor_model",
    "shifted",
    "stop_backstops",
    "validate_effects",
]
