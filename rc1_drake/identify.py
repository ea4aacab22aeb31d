"""Friction identification as stages: parameters (bounds, frozen flags) -> data (a campaign's trials)
-> residual (replays scored by paper Eq. 6) -> optimize -> report.

The paper's Alternating Variable Search (AVS, section 4, Table 1): start from the manual values,
vary one coefficient at a time over a bounded set of candidates, keep the best, move on to the next
coefficient, for a chosen number of iterations. Keeping the incumbent among the candidates makes the
error non-increasing from one iteration to the next.
"""

import dataclasses
import math
import os
from typing import Dict, List, Optional

import numpy as np

from .config import FRICTION_NAMES, Z95, Friction, Rc1Error
from .engine import default_engine
from .engine.session import sensitivity_parameters
from .executor import make_executor
from .sysid.evaluate import map_trials, replay, replayer
from .sysid.optimize import bounded_step
from .sysid.parameters import (DEFAULT_PARAMETERS, PAPER_MANUAL, Parameter, difference_step, parameter_value,
                               with_fixed, with_values)
from .sysid.residual import residual_channels, residual_jacobian, trial_residual
from .sysid.stats import channel_variances


# Resampled replays per trial for the input-noise part of every interval (uncertainty()).
INPUT_NOISE_SAMPLES = 8


def _replay_error(trial, friction: Friction, effects=None) -> float:
    from .compare import simulator_error

    run = replay(trial, friction, effects)
    return simulator_error(run.head_xy[-1], trial.final_head_xy, trial.initial_head_pose[:2])


class Eq6Objective:
    """Mean Eq. 6 error of the trials for a friction set; counts simulations, caches evaluations."""

    def __init__(self, trials, *, executor=None, effects=None):
        self.trials = list(trials)
        self.executor = executor
        self.effects = effects
        self.simulations = 0
        self._cache: Dict[tuple, float] = {}

    def per_trial(self, friction: Friction, effects=None) -> List[float]:
        errors = map_trials(_replay_error, self.trials, friction, with_fixed(self.effects, effects), self.executor)
        self.simulations += len(self.trials)
        return errors

    def __call__(self, friction: Friction, effects=None) -> float:
        key = dataclasses.astuple(friction) + tuple(sorted(with_fixed(self.effects, effects).items()))
        if key not in self._cache:
            self._cache[key] = float(np.mean(self.per_trial(friction, effects)))
        return self._cache[key]


@dataclasses.dataclass
class AvsIteration:
    iteration: int  # 1-based
    parameter: str
    candidates: List[float]
    errors: List[float]  # mean Eq. 6 error at each candidate
    best: float
    friction: Friction  # the set after this iteration
    error: float  # its mean Eq. 6 error


@dataclasses.dataclass
class AvsResult:
    start: Friction
    start_error: float
    iterations: List[AvsIteration]
    simulations: int

    @property
    def friction(self) -> Friction:
        return self.iterations[-1].friction if self.iterations else self.start

    @property
    def error(self) -> float:
        return self.iterations[-1].error if self.iterations else self.start_error

    def table(self) -> str:
        """Paper Table 1: a row per coefficient, a column per iteration; * marks the value that
        iteration chose."""
        head = f"{'Param.':<9}{'Initial':>9}" + "".join(f"{it.iteration:>9}" for it in self.iterations)
        lines = [head]
        for name in FRICTION_NAMES:
            cells = "".join(
                f"{('*' if it.parameter == name else '') + format(getattr(it.friction, name), '.4g'):>9}"
                for it in self.iterations)
            lines.append(f"{name:<9}{getattr(self.start, name):>9.4g}{cells}")
        lines.append(f"{'Eq.6 %':<9}{self.start_error:>9.2f}" + "".join(f"{it.error:>9.2f}" for it in self.iterations))
        return "\n".join(lines)

    def to_json(self) -> dict:
        return {"method": "avs", "start": dataclasses.asdict(self.start), "start_error_pct": self.start_error,
                "friction": dataclasses.asdict(self.friction), "error_pct": self.error,
                "simulations": self.simulations,
                "iterations": [{**dataclasses.asdict(it), "friction": dataclasses.asdict(it.friction)}
                               for it in self.iterations]}


def avs_candidates(value: float, parameter: Parameter, factors=(0.5, 0.75, 1.25, 1.5)) -> List[float]:
    """Candidates around the incumbent, within the bounds (the incumbent itself is always kept)."""
    base = value if value > 0 else 0.1 * (parameter.upper - parameter.lower)
    out = {min(max(base * f, parameter.lower), parameter.upper) for f in factors}
    out.discard(value)
    return sorted(out)


def avs(objective, *, start: Friction = PAPER_MANUAL, iterations: int = 10,
        parameters: Optional[List[Parameter]] = None, factors=(0.5, 0.75, 1.25, 1.5), progress=None) -> AvsResult:
    """The paper's AVS: iteration k varies the k-th free coefficient (cycling in the paper's order
    c_joint, mu_lat, mu_long, c_lat, c_long) over candidate values and keeps the best."""
    parameters = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    if not parameters:
        raise Rc1Error("identify: every coefficient is frozen; nothing to search")
    current = start
    current_error = start_error = objective(current)
    history = []
    for k in range(iterations):
        parameter = parameters[k % len(parameters)]
        value = getattr(current, parameter.name)
        candidates = [value] + avs_candidates(value, parameter, factors)
        errors = [current_error] + [objective(dataclasses.replace(current, **{parameter.name: c}))
                                    for c in candidates[1:]]
        best = int(np.argmin(errors))
        current = dataclasses.replace(current, **{parameter.name: candidates[best]})
        current_error = errors[best]
        order = np.argsort(candidates)
        history.append(AvsIteration(iteration=k + 1, parameter=parameter.name,
                                    candidates=[candidates[i] for i in order], errors=[errors[i] for i in order],
                                    best=candidates[best], friction=current, error=current_error))
        if progress:
            progress(k + 1, iterations, parameter.name, current_error)
    return AvsResult(start=start, start_error=start_error, iterations=history,
                     simulations=getattr(objective, "simulations", 0))


def identify_avs(campaign, *, trials=None, iterations=10, workers=None, scheduler=None, start=PAPER_MANUAL,
                 parameters=None, progress=None, effects=None, input_noise_samples=INPUT_NOISE_SAMPLES):
    """AVS on the chosen trials (the model with `effects`, held fixed), then the uncertainty of its
    result (uncertainty(), with `input_noise_samples`): (AvsResult, Uncertainty)."""
    chosen = campaign.chosen(trials)
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        objective = Eq6Objective(chosen, executor=executor, effects=effects)
        result = avs(objective, start=start, iterations=iterations, parameters=parameters, progress=progress)
        spread = uncertainty(CampaignResiduals(chosen, executor=executor, effects=effects), result.friction,
                             parameters=parameters, input_noise_samples=input_noise_samples)
    return result, spread


def friction_to_yaml(friction: Friction, effects=None) -> str:
    from .scenarios import model_to_yaml

    return model_to_yaml(friction, effects, comment="Identified by rc1 identify")


def load_friction_file(path) -> Friction:
    """The friction of a model file (scenarios.load_model_file); Rc1Error names the problem."""
    from .scenarios import load_model_file

    return load_model_file(path).friction


def avs_figure(result: AvsResult):
    """Error against the varied coefficient, one panel per iteration (paper Figs. 6-7)."""
    import matplotlib.pyplot as plt

    n = len(result.iterations)
    cols = min(5, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3 * cols, 2.6 * rows), squeeze=False)
    for ax, it in zip(axes.flat, result.iterations, strict=False):
        ax.plot(it.candidates, it.errors, "o-", mfc="none")
        ax.plot([it.best], [it.error], "o", color="k")
        ax.set_title(f"iteration {it.iteration}", fontsize=9)
        ax.set_xlabel(it.parameter)
        ax.set_ylabel("mean Eq. 6 error (%)")
        ax.grid(True, alpha=0.3)
    for ax in axes.flat[n:]:
        ax.axis("off")
    fig.tight_layout()
    return fig


def _replay_residual(trial, friction: Friction, effects=None) -> np.ndarray:
    return trial_residual(trial, replay(trial, friction, effects))


def _replay_residual_and_jacobian(trial, friction: Friction, effects, names) -> tuple:
    """One trial's residuals and their derivatives by the parameters `names` from one replay with exact
    sensitivities (engine/tangent.py)."""
    run = replayer(trial).run(friction, effects, sensitivities=names)
    r = trial_residual(trial, run)
    return r, residual_jacobian(trial, run, r)


def exact_jacobian_available(names) -> bool:
    """Whether replays can give the residuals' derivatives by `names` exactly (the compiled engine's
    sensitivities), in place of finite-difference columns."""
    return default_engine() == "compiled" and all(n in sensitivity_parameters() for n in names)


def _input_noise_covariance(trial, friction: Friction, effects, samples: int, seed: int, length=None) -> np.ndarray:
    """Covariance of one trial's residuals over `samples` replays with resampled angle noise; `length`:
    that of the unperturbed replay's residuals, when the caller has it (else it is replayed)."""
    own, rng = replayer(trial), np.random.default_rng(seed)
    if length is None:
        length = len(trial_residual(trial, own.run(friction, effects)))
    draws = [trial_residual(trial, own.run_resampled(friction, effects, rng)) for _ in range(samples)]
    draws = np.array([d for d in draws if len(d) == length])  # a replay that stopped elsewhere: left out
    if len(draws) < 2:
        return np.zeros((length, length))
    deviation = draws - draws.mean(axis=0)
    return deviation.T @ deviation / (len(draws) - 1)


class CampaignResiduals:
    """The stacked standardized residuals of the trials for a friction set (and effect parameters, set
    over the fixed `effects` given here); counts simulations."""

    def __init__(self, trials, *, executor=None, effects=None):
        self.trials, self.executor, self.effects = list(trials), executor, effects
        self.simulations = 0

    def __call__(self, friction: Friction, effects=None) -> np.ndarray:
        parts = map_trials(_replay_residual, self.trials, friction, with_fixed(self.effects, effects), self.executor)
        self.simulations += len(self.trials)
        self.channels = np.concatenate([residual_channels(p) for p in parts])
        return np.concatenate(parts)

    def with_jacobian(self, friction: Friction, effects, names) -> tuple:
        """(the stacked residuals, their derivatives by the parameters `names`) from one replay per trial
        (exact_jacobian_available(names) must hold)."""
        jobs = [(t, friction, with_fixed(self.effects, effects), tuple(names)) for t in self.trials]
        if self.executor is None:
            parts = [_replay_residual_and_jacobian(*job) for job in jobs]
        else:
            parts = [f.result() for f in [self.executor.submit(_replay_residual_and_jacobian, *job) for job in jobs]]
        self.simulations += len(self.trials)
        self.channels = np.concatenate([residual_channels(r) for r, _ in parts])
        return np.concatenate([r for r, _ in parts]), np.vstack([j for _, j in parts])

    def input_noise(self, friction: Friction, effects=None, *, samples: int = INPUT_NOISE_SAMPLES,
                    seed: int = 0) -> np.ndarray:
        """Block-diagonal covariance of the stacked residuals that the angle noise in the replays' input
        causes, from `samples` resampled replays per trial (plus one unperturbed)."""
        from scipy.linalg import block_diag

        jobs = [(t, friction, with_fixed(self.effects, effects), samples, seed + k)
                for k, t in enumerate(self.trials)]
        if self.executor is None:
            blocks = [_input_noise_covariance(*job) for job in jobs]
        else:
            blocks = [f.result() for f in [self.executor.submit(_input_noise_covariance, *job) for job in jobs]]
        self.simulations += (samples + 1) * len(self.trials)
        return block_diag(*blocks)


@dataclasses.dataclass
class Uncertainty:
    names: List[str]
    values: List[float]
    standard_errors: List[float]  # inf where the data do not constrain the coefficient
    correlation: List[List[float]]
    sensitivities: List[float]  # |change of the standardized residuals| for a 1% change (uncertainty())
    identifiable: List[bool]
    residual_rms: float  # of the standardized residuals
    simulations: int

    def warnings(self) -> List[str]:
        return [f"{n}: not identifiable from these trials (relative standard error "
                f"{'inf' if not math.isfinite(se) else f'{100 * se / max(abs(v), 1e-12):.0f}%'}); its value is the "
                f"start value, not a fit" for n, v, se, ok in zip(self.names, self.values, self.standard_errors,
                                                                  self.identifiable, strict=True) if not ok]

    def table(self) -> str:
        lines = [f"{'coefficient':<12}{'value':>10}{'std. error':>12}{'95% interval':>24}{'sensitivity':>13}  identifiable"]
        for n, v, se, s, ok in zip(self.names, self.values, self.standard_errors, self.sensitivities,
                                   self.identifiable, strict=True):
            ci = "-" if not math.isfinite(se) else f"[{v - Z95 * se:.4g}, {v + Z95 * se:.4g}]"
            lines.append(f"{n:<12}{v:>10.4g}{(f'{se:.3g}' if math.isfinite(se) else 'inf'):>12}{ci:>24}{s:>13.3g}  "
                         f"{'yes' if ok else 'NO'}")
        return "\n".join(lines)


def uncertainty(residuals, friction: Friction, *, parameters=None, relative_step=0.05,
                max_relative_error=0.3, effects=None, input_noise_samples: int = INPUT_NOISE_SAMPLES) -> Uncertainty:
    """Standard errors and correlations of the free parameters from the residual Jacobian at
    (`friction`, `effects`): the sandwich (J^T J)^-1 J^T S J (J^T J)^-1 of least squares with S the
    residual variance of each channel (channel_variances), plus, with `input_noise_samples`, the
    covariance that the angle noise in the replays' input causes (CampaignResiduals.input_noise: that
    many more replays per trial; INPUT_NOISE_SAMPLES by default, 0 leaves it out and understates the
    intervals several times over, docs/identification.md); a parameter is identifiable when its relative standard error
    is below `max_relative_error`. Costs one residual evaluation per free parameter, plus one.

    The Jacobian is taken in the parameters' own units (forward differences of 5% of the value, at least
    0.5% of the bounds' range for a coefficient, 2% of the range for an effect parameter), not in their
    logarithm: at a coefficient near zero a log-scale column vanishes, and with it the correlation that
    should widen the other coefficients' intervals. Sensitivities are per 1% of a coefficient's value
    (of the range where it is 0, and for effect parameters)."""
    free = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    start_sims = getattr(residuals, "simulations", 0)
    r0 = residuals(friction, effects)
    columns, per_percent = [], []
    for p in free:
        value, span = parameter_value(p.name, friction, effects), p.upper - p.lower
        h = difference_step(p, value, relative_step)
        step = h if value + h <= p.upper else -h
        columns.append((residuals(*with_values(friction, effects, {p.name: value + step})) - r0) / step)
        per_percent.append(0.01 * (abs(value) if p.is_friction and value > 0 else span))
    jac = np.column_stack(columns)
    m, n = jac.shape
    variance = channel_variances(r0, getattr(residuals, "channels", None), n)
    u, sv, vt = np.linalg.svd(jac, full_matrices=False)
    keep = sv > 1e-9 * max(sv.max(), 1e-300)
    inv = (vt[keep].T / sv[keep] ** 2) @ vt[keep]  # (J^T J)^-1 on the identifiable subspace
    spread = np.diag(variance)
    if input_noise_samples and hasattr(residuals, "input_noise"):
        spread = spread + residuals.input_noise(friction, effects, samples=input_noise_samples)
    cov = inv @ jac.T @ spread @ jac @ inv  # the least-squares estimate's covariance (sandwich)
    values = [parameter_value(p.name, friction, effects) for p in free]
    null = np.abs(vt[~keep]).max(axis=0) > 1e-6 if (~keep).any() else np.zeros(n, dtype=bool)
    se = [math.inf if null[i] else float(math.sqrt(max(cov[i, i], 0.0))) for i in range(n)]
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = np.where(np.outer(d, d) > 0, cov / np.outer(d, d), 0.0)
    identifiable = [math.isfinite(s) and s < max_relative_error * abs(v) for s, v in zip(se, values, strict=True)]
    return Uncertainty(names=[p.name for p in free], values=values, standard_errors=se,
                       correlation=np.round(corr, 4).tolist(),
                       sensitivities=[float(np.linalg.norm(c)) * k for c, k in zip(columns, per_percent, strict=True)],
                       identifiable=identifiable, residual_rms=float(np.sqrt(np.mean(r0**2))),
                       simulations=getattr(residuals, "simulations", 0) - start_sims)


@dataclasses.dataclass
class ProgramResult:
    start: Friction
    friction: Friction
    cost_start: float  # 0.5 |r|^2 of the standardized residuals
    cost: float
    iterations: int
    simulations: int
    jacobian: np.ndarray = dataclasses.field(repr=False, default=None)  # d r / d u at the result
    effects: Dict[str, float] = dataclasses.field(default_factory=dict)  # the model's effects at the result
    held: List[str] = dataclasses.field(default_factory=list)  # free, but not identifiable at the start: not fitted
    screening: Optional["Uncertainty"] = dataclasses.field(repr=False, default=None)

    def to_json(self) -> dict:
        return {"method": "program", "solver": "snopt", "start": dataclasses.asdict(self.start),
                "friction": dataclasses.asdict(self.friction), "effects": self.effects, "cost_start": self.cost_start,
                "cost": self.cost, "iterations": self.iterations, "simulations": self.simulations,
                "held_at_start": self.held,
                "screening": None if self.screening is None else dataclasses.asdict(self.screening)}


def fit_program(residuals, *, start: Friction, parameters=None, log_step: float = 0.02, max_iterations: int = 10,
                tolerance: float = 1e-2, on_iteration=None, start_effects=None) -> ProgramResult:
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
    base = np.array([max(getattr(start, p.name), 1e-3 * (p.upper - p.lower)) if p.is_friction
                     else min(max(parameter_value(p.name, start, start_effects), p.lower), p.upper) for p in free])
    lower = np.array([math.log(max(p.lower, 1e-6) / b) if p.is_friction else (p.lower - b) / s
                      for p, b, s in zip(free, base, span, strict=True)])
    upper = np.array([math.log(p.upper / b) if p.is_friction else (p.upper - b) / s
                      for p, b, s in zip(free, base, span, strict=True)])
    start_sims = getattr(residuals, "simulations", 0)

    def model_at(u):
        values = {p.name: float(b * math.exp(x) if p.is_friction else b + s * x)
                  for p, b, s, x in zip(free, base, span, u, strict=True)}
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
        scale = np.array([b * math.exp(x) if p.is_friction else s for p, b, s, x in zip(free, base, span, u, strict=True)])
        return by_value * scale

    u = np.zeros(len(free))
    r = residuals(*model_at(u))
    cost_start = cost = 0.5 * float(r @ r)
    if not free:
        return ProgramResult(start=start, friction=start, cost_start=cost, cost=cost, iterations=0,
                             simulations=getattr(residuals, "simulations", 0) - start_sims, effects=start_effects)
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
    return ProgramResult(start=start, friction=friction, cost_start=cost_start, cost=cost,
                         iterations=iterations, simulations=getattr(residuals, "simulations", 0) - start_sims,
                         jacobian=jac, effects=effects)


def screen(residuals, start: Friction, *, parameters=None, effects=None,
           input_noise_samples: int = INPUT_NOISE_SAMPLES) -> tuple:
    """Identifiability first: the uncertainty at the start, and the parameters with every free one that
    it finds not identifiable frozen at its start value, so that the fit does not wander along
    directions the data do not see (and report a number for them). Returns (parameters, Uncertainty)."""
    parameters = parameters or DEFAULT_PARAMETERS
    first = uncertainty(residuals, start, parameters=parameters, effects=effects,
                        input_noise_samples=input_noise_samples)
    hidden = {n for n, ok in zip(first.names, first.identifiable, strict=True) if not ok}
    return [dataclasses.replace(p, frozen=p.frozen or p.name in hidden) for p in parameters], first


def identify_program(campaign, *, trials=None, workers=None, scheduler=None, start=PAPER_MANUAL, parameters=None,
                     max_iterations=10, effects=None, screened=True, input_noise_samples=INPUT_NOISE_SAMPLES):
    """The program fit on the chosen trials (the model with `effects`, held fixed), then the uncertainty
    of its result over every originally free parameter. With `screened`, the parameters the start's
    uncertainty finds not identifiable stay at their start values (screen()); the result's warnings
    say so; `input_noise_samples` goes to the result's uncertainty(). Returns (ProgramResult, Uncertainty)."""
    chosen = campaign.chosen(trials)
    parameters = parameters or DEFAULT_PARAMETERS
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        residuals = CampaignResiduals(chosen, executor=executor, effects=effects)
        fitted, first = (screen(residuals, start, parameters=parameters, input_noise_samples=input_noise_samples)
                         if screened else (parameters, None))
        result = fit_program(residuals, start=start, parameters=fitted, max_iterations=max_iterations)
        spread = uncertainty(residuals, result.friction, parameters=parameters, input_noise_samples=input_noise_samples)
    result.held = [p.name for p, q in zip(parameters, fitted, strict=True) if q.frozen and not p.frozen]
    result.screening = first
    result.simulations += first.simulations if first else 0
    return result, spread


def identify_equation_error(campaign, *, trials=None, start=PAPER_MANUAL, parameters=None, effects=None, seed=0):
    """The equation-error fit (equation_error.py) on the chosen trials: no simulation."""
    from .equation_error import fit_equation_error

    return fit_equation_error(campaign.chosen(trials), start=start, parameters=parameters, effects=effects,
                              seed=seed)


def seeded_start(campaign, *, trials=None, start=PAPER_MANUAL, parameters=None) -> tuple:
    """`start` with the coefficients that equation error identifies from the chosen trials replaced by its
    estimates (no simulation): (start, EquationErrorResult or None when no trial has a camera)."""
    from .equation_error import fit_equation_error, sees_whole_configuration

    chosen = campaign.chosen(trials)
    if not any(sees_whole_configuration(t) for t in chosen):
        return start, None

    first = fit_equation_error(chosen, start=start, parameters=parameters)
    found = {n: getattr(first.friction, n) for n, ok in zip(first.names, first.identifiable, strict=True) if ok}
    return dataclasses.replace(start, **found), first


@dataclasses.dataclass
class HeldOut:
    """Mean Eq. 6 error (%) of the result on the trials it was fitted to and on held-out trials."""

    estimation_trials: List[str]
    validation_trials: List[str]
    estimation_error_pct: float
    validation_error_pct: Optional[float]  # None without held-out trials
    simulations: int

    def line(self) -> str:
        held = ("no held-out trials" if self.validation_error_pct is None else
                f"held-out {self.validation_error_pct:.2f}% ({len(self.validation_trials)} trials)")
        return (f"mean Eq. 6 error: estimation {self.estimation_error_pct:.2f}% ({len(self.estimation_trials)} trials), "
                f"{held}")


def split_trials(campaign, *, trials=None, validation=None) -> tuple:
    """(estimation, validation) trials: `trials` (all when None) and `validation` (by default the
    campaign's other trials); Rc1Error for an unknown id or a trial in both."""
    estimation = campaign.chosen(trials)
    if validation is None:
        return estimation, [t for t in campaign.trials if t not in estimation]
    held = campaign.chosen(validation)
    overlap = sorted({t.trial_id for t in held} & {t.trial_id for t in estimation})
    if overlap:
        raise Rc1Error(f"{campaign.path}: trial '{overlap[0]}' is both an estimation and a validation trial")
    return estimation, held


def held_out_errors(estimation, validation, friction: Friction, *, workers=None, scheduler=None,
                    effects=None) -> HeldOut:
    """Eq. 6 errors of `friction` (and `effects`) on the estimation and the validation trials (split_trials)."""
    everything = estimation + validation
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(everything)), scheduler=scheduler) as executor:
        errors = Eq6Objective(everything, executor=executor, effects=effects).per_trial(friction)
    k = len(estimation)
    return HeldOut(estimation_trials=[t.trial_id for t in estimation],
                   validation_trials=[t.trial_id for t in validation],
                   estimation_error_pct=float(np.mean(errors[:k])),
                   validation_error_pct=float(np.mean(errors[k:])) if validation else None,
                   simulations=len(everything))
