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
from ..sysid.stats import MAX_RELATIVE_ERROR, Uncertainty, uncertainty
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


@dataclasses.dataclass(frozen=True)
class _Coordinates:
    """The fit's coordinates u, 0 at the start: the log of each free friction coefficient over its start value, each
    free effect parameter's change over its range (so a step of 0.1 is ~10% of either)."""

    free: list
    start: Friction
    start_effects: dict
    base: np.ndarray

    @classmethod
    def at(cls, free, start: Friction, start_effects: dict) -> "_Coordinates":
        base = [
            max(getattr(start, p.name), 1e-3 * (p.upper - p.lower))
            if p.is_friction
            else min(max(parameter_value(p.name, start, start_effects), p.lower), p.upper)
            for p in free
        ]
        return cls(free, start, start_effects, np.array(base))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        def u(p, b, value):
            return math.log(max(value, 1e-6) / b) if p.is_friction else (value - b) / (p.upper - p.lower)

        pairs = [(u(p, b, p.lower), u(p, b, p.upper)) for p, b in zip(self.free, self.base, strict=True)]
        return np.array([lo for lo, _ in pairs]), np.array([hi for _, hi in pairs])

    def scale(self, u) -> np.ndarray:
        """d value / d u."""
        rows = zip(self.free, self.base, u, strict=True)
        return np.array([b * math.exp(x) if p.is_friction else p.upper - p.lower for p, b, x in rows])

    def model(self, u) -> tuple:
        """(friction, effects) at u."""
        values = {
            p.name: float(b * math.exp(x) if p.is_friction else b + (p.upper - p.lower) * x)
            for p, b, x in zip(self.free, self.base, u, strict=True)
        }
        return with_values(self.start, self.start_effects, values)


def _levenberg_marquardt(residual_at, jacobian_at, r, lower, upper, *, max_iterations, tolerance, on_step):
    """(u, cost, iterations, the last Jacobian) of Levenberg-Marquardt from u = 0 (residual r) within [lower, upper]:
    each bounded step a MathematicalProgram (sysid.optimize.bounded_step), the damping raised until the cost falls;
    stops when a step improves the cost by under `tolerance` (relative) or moves no coordinate by 1e-3."""
    u = np.zeros(lower.shape[0])
    cost = 0.5 * float(r @ r)
    damping, iterations, jac = 1.0, 0, None
    for k in range(1, max_iterations + 1):
        iterations = k
        jac = jacobian_at(u, r)
        while True:
            step = bounded_step(jac, r, damping, lower - u, upper - u)
            r_new = residual_at(u + step)
            cost_new = 0.5 * float(r_new @ r_new)
            if cost_new < cost:
                damping = max(damping / 3, 1e-6)
                break
            damping *= 4
            if damping > 1e6:
                return u, cost, iterations, jac
        u, r, improvement, cost = u + step, r_new, (cost - cost_new) / cost, cost_new
        on_step(u)
        if improvement < tolerance or np.abs(step).max() < 1e-3:
            break
    return u, cost, iterations, jac


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
    coords = _Coordinates.at(free, start, dict(start_effects or {}))
    start_sims = getattr(residuals, "simulations", 0)
    names = [p.name for p in free]
    exact = hasattr(residuals, "with_jacobian") and bool(free) and exact_jacobian_available(names)

    def residual_at(u):
        return residuals(*coords.model(u))

    def jacobian_at(u, r):
        """d r / d u: exact from the replays' sensitivities (chain rule through the log or linear scaling),
        else forward differences of log_step."""
        if not exact:
            return np.column_stack([(residual_at(u + log_step * e) - r) / log_step for e in np.eye(len(u))])
        return residuals.with_jacobian(*coords.model(u), names)[1] * coords.scale(u)

    def on_step(u):
        if on_iteration is not None:
            on_iteration(coords.model(u)[0], getattr(residuals, "simulations", 0) - start_sims)

    u = np.zeros(len(free))
    r = residual_at(u)
    cost_start = cost = 0.5 * float(r @ r)
    iterations, jac = 0, None
    if free:
        lower, upper = coords.bounds()
        u, cost, iterations, jac = _levenberg_marquardt(
            residual_at,
            jacobian_at,
            r,
            lower,
            upper,
            max_iterations=max_iterations,
            tolerance=tolerance,
            on_step=on_step,
        )
    friction, effects = coords.model(u)
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
    first = uncertainty(  # what the noise lets the data see: the trials' disagreement is for the result's interval
        residuals,
        start,
        parameters=parameters,
        effects=effects,
        input_noise_samples=input_noise_samples,
        trial_jackknife_too=False,
        fit_end=False,
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
    uncertainty finds not identifiable stay at their start values (screen()); where the noise at the fit's end
    sees one of them, it is released and the fit goes on from there (identifiability judged where the fit ended);
    the result's warnings name those still held, and the uncertainty calls none of them identifiable.
    `input_noise_samples` goes to the result's uncertainty(); `checkpoint` (evaluate.Checkpoint) keeps every
    replay's result; `on_fit(result)` is called as each fit ends, before its uncertainty. Returns (ProgramResult,
    Uncertainty)."""
    chosen = campaign.chosen(trials)
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        residuals = CampaignResiduals(chosen, executor=executor, effects=effects, checkpoint=checkpoint)
        return fit_screened(
            residuals,
            start=start,
            parameters=parameters,
            max_iterations=max_iterations,
            screened=screened,
            input_noise_samples=input_noise_samples,
            on_fit=on_fit,
        )


def fit_screened(
    residuals, *, start: Friction, parameters=None, max_iterations=10, screened=True, input_noise_samples=0, on_fit=None
):
    """identify_program's stages on `residuals` (a CampaignResiduals, or any callable of (friction, effects) with
    its attributes): the screen at the start, the fit, its uncertainty, and, where the noise at the fit's end sees
    a coefficient the screen held, the fit released there and its uncertainty again. Returns (ProgramResult,
    Uncertainty), the uncertainty calling no held coefficient identifiable."""
    parameters = parameters or DEFAULT_PARAMETERS
    fitted, first = (
        screen(residuals, start, parameters=parameters, input_noise_samples=input_noise_samples)
        if screened
        else (parameters, None)
    )

    def fitted_from(friction, free, before=None):
        result = fit_program(residuals, start=friction, parameters=free, max_iterations=max_iterations)
        result.held = [p.name for p, q in zip(parameters, free, strict=True) if q.frozen and not p.frozen]
        if before is not None:  # one fit from the first's start, counted whole
            result.start, result.cost_start = before.start, before.cost_start
            result.iterations += before.iterations
            result.simulations += before.simulations
        if on_fit:
            on_fit(result)
        spread = uncertainty(
            residuals,
            result.friction,
            parameters=parameters,
            input_noise_samples=input_noise_samples,
            fitted=[p.name for p in free if not p.frozen],
        )
        return result, spread

    result, spread = fitted_from(start, fitted)
    seen = _seen_at(spread, fitted)
    if seen:  # identifiable judged where the fit ended: the start's screen may have held what the data see here
        fitted = [dataclasses.replace(p, frozen=p.frozen and p.name not in seen) for p in fitted]
        result.simulations += spread.simulations
        result, spread = fitted_from(result.friction, fitted, before=result)
    spread.identifiable = [ok and n not in result.held for n, ok in zip(spread.names, spread.identifiable, strict=True)]
    result.screening = first
    result.simulations += first.simulations if first else 0
    return result, spread


def _seen_at(spread: Uncertainty, fitted) -> set:
    """The coefficients the fit held (`fitted`'s frozen ones among `spread`'s) whose relative standard error from
    the noise alone, at the fit's end, is below the screen's (MAX_RELATIVE_ERROR)."""
    held = {p.name for p in fitted if p.frozen}
    rows = zip(spread.names, spread.values, spread.noise_standard_errors, strict=True)
    return {n for n, v, se in rows if n in held and math.isfinite(se) and se < MAX_RELATIVE_ERROR * abs(v)}


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
