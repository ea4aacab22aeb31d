"""The identification's parameters: one Parameter type for a friction coefficient (paper Eqs. 4-5), an effect's
parameter or coordinate (rc1_drake/effects/), or a nuisance (a trial's start rate); the default set of the paper's five
coefficients, and the values a model takes when some of them are set. (effects.EffectParameter is an effect's
declaration of its parameters: key, bounds, default, probe step; a fit makes Parameters of it.)
"""

import dataclasses

from ..config import FRICTION_NAMES, Friction
from ..effects import LIBRARY, parameter

# The paper's manually tuned starting point (section 4).
PAPER_MANUAL = Friction(c_joint=0.045, mu_lat=1.5, mu_long=0.1, c_lat=2.0, c_long=0.1)


@dataclasses.dataclass
class Parameter:
    name: str  # a Friction field, an effect parameter's or coordinate's key (effects/), or "<trial>:<start rate>"
    lower: float
    upper: float
    frozen: bool = False  # held at its value by a fit
    owner: str = "friction"  # "friction", the effect's name, or "start" (a trial's start: a nuisance)
    value: float = 0.0  # where a linearization takes it
    step: float = 0.0  # its forward-difference step there
    start_of: tuple | None = None  # a start's (trial index, index in start.START_NAMES)

    @property
    def is_friction(self) -> bool:
        return self.name in FRICTION_NAMES


DEFAULT_PARAMETERS = [
    Parameter("c_joint", 0.0, 0.5),
    Parameter("mu_lat", 0.05, 5.0),
    Parameter("mu_long", 0.0, 1.0),
    Parameter("c_lat", 0.0, 20.0),
    Parameter("c_long", 0.0, 2.0),
]


def effect_parameters(name: str) -> list[Parameter]:
    """The fitted parameters of effect `name`, with its bounds."""
    return [Parameter(p.key, p.lower, p.upper, owner=name) for p in LIBRARY[name].fitted()]


def parameter_value(name: str, friction: Friction, effects=None) -> float:
    """A friction coefficient's, or an effect parameter's value (its default where `effects` leaves it out)."""
    if name in FRICTION_NAMES:
        return getattr(friction, name)
    return float((effects or {}).get(name, parameter(name).default))


def with_values(friction: Friction, effects, values: dict[str, float]) -> tuple:
    """(friction, effects) with `values` (friction coefficients and effect parameters by name) set."""
    return (
        dataclasses.replace(friction, **{k: v for k, v in values.items() if k in FRICTION_NAMES}),
        {**(effects or {}), **{k: v for k, v in values.items() if k not in FRICTION_NAMES}},
    )


def with_fixed(fixed, effects) -> dict:
    """The model's fixed effects with `effects` (the ones being varied) set over them."""
    return {**(fixed or {}), **(effects or {})}


def difference_step(parameter: Parameter, value: float, relative_step: float = 0.05) -> float:
    """The forward-difference step of a parameter at `value`: relative_step of the value, at least 0.5% of
    the bounds' range for a friction coefficient; 2% of the range for an effect parameter."""
    span = parameter.upper - parameter.lower
    return max(relative_step * abs(value), 0.005 * span) if parameter.is_friction else 0.02 * span
