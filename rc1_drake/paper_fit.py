"""The paper's section-4 figures as the targets of a fit (issue 41): a mechanism's parameters — friction
coefficients, effect parameters, the working servos' gains — searched by the paper's own AVS (identify.avs.avs) so
that the model's outcomes (reproduce.py) match the paper's numbers. Each target is a standardized shortfall, 0 where
the finding holds: J2's two counter-clockwise revolutions and 0.56 m circle (Fig. 10), J3-J6 circling, J7's final
y within -2 to -1 m (Fig. 11), the nominal's within +0.25 to +1 m (Fig. 8), J13 forward with |y| <= 1 m (Fig. 12).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .config import FRICTION_NAMES, SERVO_NAMES, Friction, Servo
from .effects import parameter_owner
from .reproduce import CIRCLING_REVOLUTIONS, DIAMETER_TOLERANCE, SLIGHT_DRIFT_M, reproduce
from .sysid.parameters import Parameter

PAPER_DIAMETER_M = 0.56  # Fig. 10: J2's mean circle
BAND_SCALE_M = 0.25  # a final y this far outside the paper's band is one unit of misfit (a quarter of its width)
REVOLUTION_SCALE = 0.5  # half a revolution short of the paper's two is one unit
FIT_CASES = (2, 3, 6, 7, 13)  # J2 and the two ends of J3-J6 (their circling), J7 and J13 (forward); none always runs


def _band(value: float, lower: float, upper: float) -> float:
    return max(lower - value, value - upper, 0.0) / BAND_SCALE_M


def _signed_revolutions(trial) -> float:
    """Revolutions, counter-clockwise positive (the paper's J2 turned CCW; a CW circle counts against it)."""
    return trial.revolutions if trial.direction != "CW" else -trial.revolutions


def paper_residuals(result) -> dict[str, float]:
    """Per target, the model's standardized shortfall from the paper's number (mean over a case's trials)."""
    cases, out = result.cases, {}
    for joint in (j for j in range(2, 7) if f"J{j}" in cases):
        revs = [min(_signed_revolutions(t), CIRCLING_REVOLUTIONS) for t in cases[f"J{joint}"].trials]
        out[f"J{joint} revolutions"] = float(np.mean([(CIRCLING_REVOLUTIONS - r) / REVOLUTION_SCALE for r in revs]))
    if "J2" in cases:
        circled = [t.circle_diameter_m for t in cases["J2"].trials if t.circle_diameter_m and t.revolutions >= 1]
        scale = DIAMETER_TOLERANCE * PAPER_DIAMETER_M
        out["J2 diameter"] = (
            float(np.mean([abs(d - PAPER_DIAMETER_M) / scale for d in circled]))
            if circled
            else PAPER_DIAMETER_M / scale
        )
    bands = {"none": (0.25, 1.0), "J7": (-2.0, -1.0), "J13": (-SLIGHT_DRIFT_M, SLIGHT_DRIFT_M)}
    for label, (lower, upper) in ((k, v) for k, v in bands.items() if k in cases):
        out[f"{label} final y"] = float(np.mean([_band(y, lower, upper) for y in cases[label].final_y_m]))
    return out


def paper_cost(result) -> float:
    """Mean square of paper_residuals: 0 when every target holds."""
    r = np.array(list(paper_residuals(result).values()))
    return float(r @ r / len(r))


def mechanism_parameter(name: str, lower: float, upper: float) -> Parameter:
    """A parameter of the fit by name: a friction coefficient, a servo gain (SERVO_NAMES) or an effect parameter."""
    effect = parameter_owner(name)
    if name not in FRICTION_NAMES and name not in SERVO_NAMES and effect is None:
        known = ", ".join([*FRICTION_NAMES, *SERVO_NAMES, "or an effect parameter (rc1 effects)"])
        raise ValueError(f"unknown parameter '{name}' (known: {known})")
    owner = "friction" if name in FRICTION_NAMES else "servo" if name in SERVO_NAMES else effect.name
    return Parameter(name, lower, upper, owner=owner)


def fit_table(objective: PaperObjective) -> str:
    """Every point the fit evaluated, in order: its values, its cost and each target's shortfall."""
    if not objective.history:
        return ""
    names, targets = list(objective.history[0][0]), list(objective.history[0][2])
    lines = ["  ".join([*(f"{n:>16}" for n in names), f"{'cost':>7}", *(f"{t:>15}" for t in targets)])]
    for values, cost, residuals in objective.history:
        cells = [f"{values[n]:>16.4g}" for n in names] + [f"{cost:>7.3f}"]
        lines.append("  ".join(cells + [f"{residuals.get(t, math.nan):>15.2f}" for t in targets]))
    return "\n".join(lines)


def model_of(values: dict[str, float], *, friction=None, effects=None, servo=None) -> tuple:
    """(friction, effects, servo) with the fit's `values` written over the given model."""
    friction = dataclasses.replace(friction or Friction(), **{k: v for k, v in values.items() if k in FRICTION_NAMES})
    servo = dataclasses.replace(servo or Servo(), **{k: v for k, v in values.items() if k in SERVO_NAMES})
    moved = {k: v for k, v in values.items() if k not in FRICTION_NAMES and k not in SERVO_NAMES}
    return friction, {**(effects or {}), **moved}, servo


class PaperObjective:
    """paper_cost of the model with a point's values (a dataclass with one field per parameter, as avs() moves
    them), over FIT_CASES with `trials` each; counts its runs and keeps every evaluation."""

    def __init__(self, *, trials=2, workers=None, base=None):
        self.trials, self.workers, self.base = trials, workers, base or {}
        self.simulations, self.history = 0, []

    def __call__(self, point) -> float:
        values = dataclasses.asdict(point)
        friction, effects, servo = model_of(values, **self.base)
        result = reproduce(friction=friction, effects=effects, servo=servo, joints=FIT_CASES, trials=self.trials,
                           workers=self.workers)  # fmt: skip
        self.simulations += sum(len(c.trials) for c in result.cases.values())
        cost = paper_cost(result)
        self.history.append((values, cost, paper_residuals(result)))
        return cost if math.isfinite(cost) else math.inf


def fit_to_paper(parameters: list[Parameter], start: dict[str, float], *, iterations=8, trials=2, workers=None,
                 base=None, progress=None) -> tuple:  # fmt: skip
    """The paper's AVS (identify.avs.avs) over `parameters` from `start`, on PaperObjective: (AvsResult, objective).
    The result's friction field holds the point (a dataclass of the parameters' values)."""
    from .identify.avs import avs

    point = dataclasses.make_dataclass("Point", [(p.name, float) for p in parameters], frozen=True)(**start)
    objective = PaperObjective(trials=trials, workers=workers, base=base)
    result = avs(objective, start=point, iterations=iterations, parameters=parameters, progress=progress)
    return result, objective
