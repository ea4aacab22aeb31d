"""Least squares of the standardized residuals (final position, camera path or yaw rate) by Levenberg-Marquardt
steps solved as Drake MathematicalPrograms, screened for identifiability first and started where equation error
puts the coefficients it identifies."""

import dataclasses
import math
import os
from typing import Optional

import numpy as np

from ..config import Friction
from ..executor import make_executor
from ..sysid.input_noise import INPUT_NOISE_SAMPLES
from ..sysid.objective import CampaignResiduals
from ..sysid.optimize import bounded_step
from ..sysid.parameters import DEFAULT_PARAMETERS, PAPER_MANUAL, parameter_value, with_values
from ..sysid.residual import exact_jacobian_available
from ..sysid.stats import Uncertainty, uncertainty
from .equation_error import fit_equation_error, sees_whole_configuration


@dataclasses.dataclass
class ProgramResult:
    start: Friction
    friction: Friction
    cost_start: float  # 0.5 |r|^2 of the standardized residuals
    cost: float
    iterations: int
    simulations: int
    jacobian: np.ndarray = dataclasses.field(repr=False, default=None)  # d r / d u at the result
    effects: dict[str, float] = dataclasses.field(default_factory=dict)  # the model's effects at the result
    held: list[str] = dataclasses.field(default_factory=list)  # free, but not identifiable at the start: not fitted
    screening: Optional["Uncertainty"] = dataclasses.field(repr=False, default=None)

    def to_json(self) -> dict:
        return {
            "method": "program",
            "solver": "snopt",
            "start": dataclasses.asdict(self.start),
            "friction": dataclasses.asdict(self.friction),
            "effects": self.effects,
            "cost_start": self.cost_start,
            "cost": self.cost,
            "iterations": self.iterations,
            "simulations": self.simulations,
            "held_at_start": self.held,
            "screening": None if self.screening is None else dataclasses.asdict(self.screening),
        }


def fit_program(
    residuals,
    *,
    start: Friction,
    parameters=None,
    log_step: float = 0.02,
    max_iterations: int = 10,
    tolerance: float = 1e-2,
    on_iteration=None,
    start_effects=None,
) -> ProgramResult:
    """Least squares of the standardized residuals (final position, yaw rate, camera path) over the log
    of each free friction coefficient and the value of each free effect parameter (scaled by its range),
    within bounds: Levenberg-Marquardt iterations whose bounded steps are Drake MathematicalPrograms
    solved by SNOPT. The Jacobian is exact where the compiled engine differentiates the replays (one
    replay per trial per iteration, engine/tangent.py), else forward differences (one residual evaluation
    per free parameter per iteration). `on_iteration(friction, simulations)`,
    if given, is called after every accepted step."""
    free = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    start_effects = dict(start_effects or {})
    span = np.array([1.0 if p.is_friction else p.upper - p.lower for p in free])
    base = np.array(
        [
            max(getattr(start, p.name), 1e-3 * (p.upper - p.lower))
            if p.is_friction
            else min(max(parameter_value(p.name, start, start_effects), p.lower), p.upper)
            for p in free
        ]
    )
    lower = np.array(
        [
            math.log(max(p.lower, 1e-6) / b) if p.is_friction else (p.lower - b) / s
            for p, b, s in zip(free, base, span, strict=True)
        ]
    )
    upper = np.array(
        [
            math.log(p.upper / b) if p.is_friction else (p.upper - b) / s
            for p, b, s in zip(free, base, span, strict=True)
        ]
    )
    start_sims = getattr(residuals, "simulations", 0)

    def model_at(u):
        values = {
            p.name: float(b * math.exp(x) if p.is_friction else b + s * x)
            for p, b, s, x in zip(free, base, span, u, strict=True)
        }
        return with_values(start, start_effects, values)

    def friction_at(u):
        return model_at(u)[0]

    names = [p.name for p in free]
    exact = hasattr(residuals, "with_jacobian") and bool(free) and exact_jacobian_available(names)

    def jacobian_at(u, r):
        """d r / d u: exact from the replays' sensitivities (chain rule through the log or linear scaling),
        else forward differences of log_step."""
        if not exact:
            return np.column_stack([(residuals(*model_at(u + log_step * e)) - r) / log_step for e in np.eye(len(u))])
        _, by_value = residuals.with_jacobian(*model_at(u), names)
        scale = np.array(
            [b * math.exp(x) if p.is_friction else s for p, b, s, x in zip(free, base, span, u, strict=True)]
        )
        return by_value * scale

    u = np.zeros(len(free))
    r = residuals(*model_at(u))
    cost_start = cost = 0.5 * float(r @ r)
    if not free:
        return ProgramResult(
            start=start,
            friction=start,
            cost_start=cost,
            cost=cost,
            iterations=0,
            simulations=getattr(residuals, "simulations", 0) - start_sims,
            effects=start_effects,
        )
    damping, iterations = 1.0, 0
    jac = None
    for k in range(1, max_iterations + 1):
        iterations = k
        jac = jacobian_at(u, r)
        while True:
            step = bounded_step(jac, r, damping, lower - u, upper - u)
            r_new = residuals(*model_at(u + step))
            cost_new = 0.5 * float(r_new @ r_new)
            if cost_new < cost:
                damping = max(damping / 3, 1e-6)
                break
            damping *= 4
            if damping > 1e6:
                step = None
                break
        if step is None:
            break
        u, r, improvement, cost = u + step, r_new, (cost - cost_new) / cost, cost_new
        if on_iteration is not None:
            on_iteration(friction_at(u), getattr(residuals, "simulations", 0) - start_sims)
        if improvement < tolerance or np.abs(step).max() < 1e-3:
            break
    friction, effects = model_at(u)
    return ProgramResult(
        start=start,
        friction=friction,
        cost_start=cost_start,
        cost=cost,
        iterations=iterations,
        simulations=getattr(residuals, "simulations", 0) - start_sims,
        jacobian=jac,
        effects=effects,
    )


def screen(
    residuals, start: Friction, *, parameters=None, effects=None, input_noise_samples: int = INPUT_NOISE_SAMPLES
) -> tuple:
    """Identifiability first: the uncertainty at the start, and the parameters with every free one that
    it finds not identifiable frozen at its start value, so that the fit does not wander along
    directions the data do not see (and report a number for them). Returns (parameters, Uncertainty)."""
    parameters = parameters or DEFAULT_PARAMETERS
    first = uncertainty(
        residuals, start, parameters=parameters, effects=effects, input_noise_samples=input_noise_samples
    )
    hidden = {n for n, ok in zip(first.names, first.identifiable, strict=True) if not ok}
    return [dataclasses.replace(p, frozen=p.frozen or p.name in hidden) for p in parameters], first


def identify_program(
    campaign,
    *,
    trials=None,
    workers=None,
    scheduler=None,
    start=PAPER_MANUAL,
    parameters=None,
    max_iterations=10,
    effects=None,
    screened=True,
    input_noise_samples=INPUT_NOISE_SAMPLES,
    checkpoint=None,
    on_fit=None,
):
    """The program fit on the chosen trials (the model with `effects`, held fixed), then the uncertainty
    of its result over every originally free parameter. With `screened`, the parameters the start's
    uncertainty finds not identifiable stay at their start values (screen()); the result's warnings
    say so; `input_noise_samples` goes to the result's uncertainty(); `checkpoint` (evaluate.Checkpoint) keeps every
    replay's result; `on_fit(result)` is called as the fit ends, before its uncertainty. Returns (ProgramResult,
    Uncertainty)."""
    chosen = campaign.chosen(trials)
    parameters = parameters or DEFAULT_PARAMETERS
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        residuals = CampaignResiduals(chosen, executor=executor, effects=effects, checkpoint=checkpoint)
        fitted, first = (
            screen(residuals, start, parameters=parameters, input_noise_samples=input_noise_samples)
            if screened
            else (parameters, None)
        )
        result = fit_program(residuals, start=start, parameters=fitted, max_iterations=max_iterations)
        result.held = [p.name for p, q in zip(parameters, fitted, strict=True) if q.frozen and not p.frozen]
        if on_fit:
            on_fit(result)
        spread = uncertainty(residuals, result.friction, parameters=parameters, input_noise_samples=input_noise_samples)
    result.screening = first
    result.simulations += first.simulations if first else 0
    return result, spread


def identify_equation_error(campaign, *, trials=None, start=PAPER_MANUAL, parameters=None, effects=None, seed=0):
    """The equation-error fit (equation_error.py) on the chosen trials: no simulation."""
    return fit_equation_error(campaign.chosen(trials), start=start, parameters=parameters, effects=effects, seed=seed)


def seeded_start(campaign, *, trials=None, start=PAPER_MANUAL, parameters=None) -> tuple:
    """`start` with the coefficients that equation error identifies from the chosen trials replaced by its
    estimates (no simulation): (start, EquationErrorResult or None when no trial has a camera)."""
    chosen = campaign.chosen(trials)
    if not any(sees_whole_configuration(t) for t in chosen):
        return start, None

    first = fit_equation_error(chosen, start=start, parameters=parameters)
    found = {n: getattr(first.friction, n) for n, ok in zip(first.names, first.identifiable, strict=True) if ok}
    return dataclasses.replace(start, **found), first
