"""The diagnosis's coordinates: the directions of its linearization, each a sysid Parameter (a friction coefficient,
one coordinate of an effect, or one of a trial's start rates) with its value and step, and the model or trials they
set."""

import dataclasses
import math

from ..config import Friction
from ..effects import LIBRARY, effect_values
from ..start import START_NAMES
from ..sysid.parameters import DEFAULT_PARAMETERS, Parameter, difference_step

# A trial's start (its head's vx, vy, yaw rate at t = 0) as nuisance coordinates: forward-difference steps
# and bounds (m/s, m/s, rad/s). Its first START_FIT_S of data, not a convention, fix it in every fit (fit).
START = "start"
START_STEPS = (0.02, 0.02, 0.1)
START_BOUNDS = (1.0, 1.0, 5.0)


def coordinate_bounds(name: str) -> tuple[float, float]:
    """A coordinate's bounds by name: a friction coefficient's, an effect coordinate's (a start's are unbounded)."""
    for p in DEFAULT_PARAMETERS:
        if p.name == name:
            return p.lower, p.upper
    for p in (p for e in LIBRARY.values() for p in e.coordinate_space()):
        if p.key == name:
            return p.lower, p.upper
    return -math.inf, math.inf


def friction_coordinates(friction: Friction, held=()) -> list[Parameter]:
    out = []
    for p in [p for p in DEFAULT_PARAMETERS if p.name not in held]:
        value = getattr(friction, p.name)
        out.append(dataclasses.replace(p, value=value, step=difference_step(p, value)))
    return out


def effect_coordinates(name: str, effects: dict[str, float]) -> list[Parameter]:
    effect = LIBRARY[name]
    values = effect.coordinates(effect_values(effects, effect))
    return [
        Parameter(
            p.key,
            min(p.lower, values[p.key]),
            max(p.upper, values[p.key]),
            owner=name,
            value=float(values[p.key]),
            step=p.probe_step,
        )
        for p in effect.coordinate_space()
    ]


def start_coordinates(trials) -> list[Parameter]:
    """Each trial's head rates at t = 0 (Trial.initial_head_rates, which must be set) as three coordinates."""
    return [
        Parameter(
            f"{t.trial_id}:{name}",
            -bound,
            bound,
            owner=START,
            value=float(t.initial_head_rates[i]),
            step=step,
            start_of=(k, i),
        )
        for k, t in enumerate(trials)
        for i, (name, step, bound) in enumerate(zip(START_NAMES, START_STEPS, START_BOUNDS, strict=True))
    ]


def starts_at(trials, coordinates: list[Parameter], values) -> list:
    """`trials` with their START coordinates among `coordinates` set to `values`."""
    out = list(trials)
    for c, v in zip(coordinates, values, strict=True):
        if c.owner == START:
            k, i = c.start_of
            rates = out[k].initial_head_rates.copy()
            rates[i] = float(v)
            out[k] = dataclasses.replace(out[k], initial_head_rates=rates)
    return out


def physics_names(lin, names) -> list[str]:
    """`names` without the trials' start coordinates: the model's parameters (what the misfit's dof count)."""
    return [n for n in names if lin.coordinate(n).owner != START]


def model_at(friction: Friction, effects: dict[str, float], coordinates: list[Parameter], values) -> tuple:
    """(friction, effects) with the coordinates set to `values` (effects written back through their classes;
    START coordinates belong to the trials: starts_at)."""
    friction = dataclasses.replace(
        friction, **{c.name: float(v) for c, v in zip(coordinates, values, strict=True) if c.owner == "friction"}
    )
    effects = dict(effects)
    for owner in dict.fromkeys(c.owner for c in coordinates if c.owner not in ("friction", START)):
        effect = LIBRARY[owner]
        current = effect.coordinates(effect_values(effects, effect))
        current.update({c.name: float(v) for c, v in zip(coordinates, values, strict=True) if c.owner == owner})
        effects.update(effect.from_coordinates(current))
    return friction, effects


def coordinate_values(coords, friction, effects, trials) -> list[float]:
    values = []
    for c in coords:
        if c.owner == START:
            values.append(float(trials[c.start_of[0]].initial_head_rates[c.start_of[1]]))
        elif c.owner == "friction":
            values.append(getattr(friction, c.name))
        else:
            effect = LIBRARY[c.owner]
            values.append(float(effect.coordinates(effect_values(effects, effect))[c.name]))
    return values


def acts_in_failed_joints_only(c: Parameter) -> bool:
    if c.owner in ("friction", START):
        return c.name == "c_joint"
    return LIBRARY[c.owner].failed_joints_only


def signed_step(c: Parameter) -> float:
    return c.step if c.value + c.step <= c.upper else -c.step
