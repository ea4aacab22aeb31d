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

from .config import FRICTION_NAMES, Friction, Rc1Error
from .executor import make_executor

# The paper's manually tuned starting point (section 4).
PAPER_MANUAL = Friction(c_joint=0.045, mu_lat=1.5, mu_long=0.1, c_lat=2.0, c_long=0.1)


@dataclasses.dataclass
class Parameter:
    name: str  # a Friction field
    lower: float
    upper: float
    frozen: bool = False


DEFAULT_PARAMETERS = [
    Parameter("c_joint", 0.0, 0.5),
    Parameter("mu_lat", 0.05, 5.0),
    Parameter("mu_long", 0.0, 1.0),
    Parameter("c_lat", 0.0, 20.0),
    Parameter("c_long", 0.0, 2.0),
]


_REPLAYERS: dict = {}  # per worker process: trial source -> Replayer (its Diagram and reference)


def _replay(trial, friction: Friction, effects=None):
    """Replay `trial`, reusing this process's Replayer for it."""
    from .replay import Replayer

    key = str(trial.source or trial.trial_id)
    if key not in _REPLAYERS:
        _REPLAYERS[key] = Replayer(trial)
    return _REPLAYERS[key].run(friction, effects)


def _map_trials(function, trials, friction, effects, executor) -> list:
    """function(trial, friction, effects) for every trial, in this process or on the executor."""
    if executor is None:
        return [function(t, friction, effects) for t in trials]
    return [f.result() for f in [executor.submit(function, t, friction, effects) for t in trials]]


def _replay_error(trial, friction: Friction, effects=None) -> float:
    from .compare import simulator_error

    run = _replay(trial, friction, effects)
    return simulator_error(run.head_xy[-1], trial.final_head_xy, trial.initial_head_pose[:2])


class Eq6Objective:
    """Mean Eq. 6 error of the trials for a friction set; counts simulations, caches evaluations."""

    def __init__(self, trials, *, executor=None, effects=None):
        self.trials = list(trials)
        self.executor = executor
        self.effects = effects
        self.simulations = 0
        self._cache: Dict[tuple, float] = {}

    def per_trial(self, friction: Friction) -> List[float]:
        errors = _map_trials(_replay_error, self.trials, friction, self.effects, self.executor)
        self.simulations += len(self.trials)
        return errors

    def __call__(self, friction: Friction) -> float:
        key = dataclasses.astuple(friction)
        if key not in self._cache:
            self._cache[key] = float(np.mean(self.per_trial(friction)))
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


def choose_trials(campaign, trial_ids=None) -> list:
    """The campaign's trials with these ids (all when None); Rc1Error for an id it does not have."""
    missing = sorted(set(trial_ids or []) - {t.trial_id for t in campaign.trials})
    if missing:
        raise Rc1Error(f"{campaign.path}: no trial '{missing[0]}' in the campaign")
    return [t for t in campaign.trials if trial_ids is None or t.trial_id in trial_ids]


def identify_avs(campaign, *, trials=None, iterations=10, workers=None, scheduler=None, start=PAPER_MANUAL,
                 parameters=None, progress=None):
    """AVS on the chosen trials, then the uncertainty of its result: (AvsResult, Uncertainty)."""
    chosen = choose_trials(campaign, trials)
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        objective = Eq6Objective(chosen, executor=executor)
        result = avs(objective, start=start, iterations=iterations, parameters=parameters, progress=progress)
        spread = uncertainty(CampaignResiduals(chosen, executor=executor), result.friction, parameters=parameters)
    return result, spread


def friction_to_yaml(friction: Friction) -> str:
    lines = ["# Friction coefficients (rc1_drake.config.Friction); read with --friction-file."]
    lines += [f"{name}: {getattr(friction, name):.6g}" for name in FRICTION_NAMES]
    return "\n".join(lines) + "\n"


def load_friction_file(path) -> Friction:
    """A friction YAML (as written by `rc1 identify --out`), validated; Rc1Error names the problem."""
    from pydrake.common.yaml import yaml_load_typed

    from .config import Scenario, validate

    try:
        friction = yaml_load_typed(schema=Friction, filename=str(path))
    except FileNotFoundError:
        raise Rc1Error(f"{path}: no such friction file") from None
    except Exception as e:  # noqa: BLE001 - any parse failure is a malformed file
        raise Rc1Error(f"{path}: {' '.join(str(e).split())}") from None
    validate(Scenario(friction=friction), where=str(path))
    return friction


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


# Residual weights: roughly the measurement noise of each channel (data/README.md), so the residual
# vector is standardized and its Jacobian gives a Fisher information.
RESIDUAL_SIGMAS = {"final_m": 0.01, "yaw_rate_rad_s": 0.05, "camera_m": 0.01}
RESIDUAL_PERIOD_S = 0.1


def trial_residual(trial, run) -> np.ndarray:
    """Standardized residuals of one replay: the final head position and, every RESIDUAL_PERIOD_S, the
    head's x and y where the camera saw it, or its yaw rate when the trial has no camera.

    Why not both: the replayed yaw rate differs from a noise-free truth's by ~0.05 rad/s RMS whatever
    the friction (stiff replay servos are not the robot's servos, and the smoothed potentiometer noise
    shakes the head), so with a camera that channel adds systematic error that biases the fit more than
    it informs it; the camera's positions match to ~2 mm at the true coefficients (measured on a 3 s
    joint-7 trial)."""
    t = trial.t - trial.t[0]
    step = max(1, int(round(RESIDUAL_PERIOD_S / (t[1] - t[0]))))
    keep = np.zeros(len(t), dtype=bool)
    keep[::step] = True
    keep &= t <= run.t[-1] + 1e-9
    parts = [(run.head_xy[-1] - trial.final_head_xy) / RESIDUAL_SIGMAS["final_m"]]
    if trial.camera is not None:
        seen = keep & ~np.isnan(trial.camera[:, 0])
        for i in (0, 1):
            parts.append((np.interp(t[seen], run.t, run.head_xy[:, i]) - trial.camera[seen, i]) / RESIDUAL_SIGMAS["camera_m"])
    else:
        parts.append((np.interp(t[keep], run.t, run.head_yaw_rate) - trial.head_yaw_rate[keep])
                     / RESIDUAL_SIGMAS["yaw_rate_rad_s"])
    return np.concatenate(parts)


def _replay_residual(trial, friction: Friction, effects=None) -> np.ndarray:
    return trial_residual(trial, _replay(trial, friction, effects))


class CampaignResiduals:
    """The stacked standardized residuals of the trials for a friction set; counts simulations."""

    def __init__(self, trials, *, executor=None, effects=None):
        self.trials, self.executor, self.effects = list(trials), executor, effects
        self.simulations = 0

    def __call__(self, friction: Friction) -> np.ndarray:
        parts = _map_trials(_replay_residual, self.trials, friction, self.effects, self.executor)
        self.simulations += len(self.trials)
        return np.concatenate(parts)


@dataclasses.dataclass
class Uncertainty:
    names: List[str]
    values: List[float]
    standard_errors: List[float]  # inf where the data do not constrain the coefficient
    correlation: List[List[float]]
    sensitivities: List[float]  # |d residual / d log(coefficient)|: how much the data see a 1% change, x100
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
            ci = "-" if not math.isfinite(se) else f"[{v - 1.96 * se:.4g}, {v + 1.96 * se:.4g}]"
            lines.append(f"{n:<12}{v:>10.4g}{(f'{se:.3g}' if math.isfinite(se) else 'inf'):>12}{ci:>24}{s:>13.3g}  "
                         f"{'yes' if ok else 'NO'}")
        return "\n".join(lines)


def uncertainty(residuals, friction: Friction, *, parameters=None, relative_step=0.05,
                max_relative_error=0.3) -> Uncertainty:
    """Standard errors and correlations of the free coefficients from the residual Jacobian at
    `friction` (forward differences in log-coefficient), cov = s^2 (J^T J)^-1 with s^2 the residual
    variance; a coefficient is identifiable when its relative standard error is below
    `max_relative_error`. Costs one residual evaluation per free coefficient, plus one."""
    free = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    start_sims = getattr(residuals, "simulations", 0)
    r0 = residuals(friction)
    columns = []
    for p in free:
        value = getattr(friction, p.name)
        base = value if value > 0 else 1e-3 * (p.upper - p.lower)
        h = relative_step * base
        step = h if base + h <= p.upper else -h
        shifted = dataclasses.replace(friction, **{p.name: base + step})
        columns.append((residuals(shifted) - r0) / step * base)  # d r / d log(theta)
    jac = np.column_stack(columns)
    m, n = jac.shape
    s2 = float(r0 @ r0) / max(m - n, 1)
    u, sv, vt = np.linalg.svd(jac, full_matrices=False)
    keep = sv > 1e-9 * max(sv.max(), 1e-300)
    inv = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    cov_log = s2 * inv
    values = [getattr(friction, p.name) for p in free]
    null = np.abs(vt[~keep]).max(axis=0) > 1e-6 if (~keep).any() else np.zeros(n, dtype=bool)
    se = [math.inf if null[i] else float(abs(values[i]) * math.sqrt(max(cov_log[i, i], 0.0))) for i in range(n)]
    d = np.sqrt(np.clip(np.diag(cov_log), 1e-300, None))
    corr = np.where(np.outer(d, d) > 0, cov_log / np.outer(d, d), 0.0)
    identifiable = [math.isfinite(s) and s < max_relative_error * abs(v) for s, v in zip(se, values, strict=True)]
    return Uncertainty(names=[p.name for p in free], values=values, standard_errors=se,
                       correlation=np.round(corr, 4).tolist(), sensitivities=[float(np.linalg.norm(c)) / 100 for c in columns],
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
    jacobian: np.ndarray = dataclasses.field(repr=False, default=None)  # d r / d log(theta) at the result

    def to_json(self) -> dict:
        return {"method": "program", "solver": "snopt", "start": dataclasses.asdict(self.start),
                "friction": dataclasses.asdict(self.friction), "cost_start": self.cost_start, "cost": self.cost,
                "iterations": self.iterations, "simulations": self.simulations}


def _bounded_step(jac, r, damping, lower, upper):
    """The Levenberg-Marquardt step as a Drake MathematicalProgram solved by SNOPT:
    min |r + J d|^2 + damping |d|^2 subject to lower <= d <= upper."""
    from pydrake.solvers import MathematicalProgram, SnoptSolver

    n = jac.shape[1]
    prog = MathematicalProgram()
    d = prog.NewContinuousVariables(n, "step")
    prog.Add2NormSquaredCost(np.vstack([jac, math.sqrt(damping) * np.eye(n)]), np.concatenate([-r, np.zeros(n)]), d)
    prog.AddBoundingBoxConstraint(lower, upper, d)
    result = SnoptSolver().Solve(prog, np.zeros(n))
    if not result.is_success():
        raise Rc1Error(f"identify: SNOPT failed on a step ({result.get_solution_result()})")
    return result.GetSolution(d)


def fit_program(residuals, *, start: Friction, parameters=None, log_step: float = 0.02, max_iterations: int = 10,
                tolerance: float = 1e-2, on_iteration=None) -> ProgramResult:
    """Least squares of the standardized residuals (final position, yaw rate, camera path) over the log
    of each free coefficient, within its bounds: Levenberg-Marquardt iterations whose bounded steps are
    Drake MathematicalPrograms solved by SNOPT. The simulation is not differentiable, so the Jacobian
    comes from forward differences (one residual evaluation per free coefficient per iteration).
    `on_iteration(friction, simulations)`, if given, is called after every accepted step."""
    free = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    base = np.array([max(getattr(start, p.name), 1e-3 * (p.upper - p.lower)) for p in free])
    lower = np.array([math.log(max(p.lower, 1e-6) / b) for p, b in zip(free, base, strict=True)])
    upper = np.array([math.log(p.upper / b) for p, b in zip(free, base, strict=True)])
    start_sims = getattr(residuals, "simulations", 0)

    def friction_at(u):
        return dataclasses.replace(start, **{p.name: float(b * math.exp(x)) for p, b, x in zip(free, base, u, strict=True)})

    u = np.zeros(len(free))
    r = residuals(friction_at(u))
    cost_start = cost = 0.5 * float(r @ r)
    damping, iterations = 1.0, 0
    jac = None
    for k in range(1, max_iterations + 1):
        iterations = k
        jac = np.column_stack([(residuals(friction_at(u + log_step * e)) - r) / log_step for e in np.eye(len(u))])
        while True:
            step = _bounded_step(jac, r, damping, lower - u, upper - u)
            r_new = residuals(friction_at(u + step))
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
    return ProgramResult(start=start, friction=friction_at(u), cost_start=cost_start, cost=cost,
                         iterations=iterations, simulations=getattr(residuals, "simulations", 0) - start_sims,
                         jacobian=jac)


def identify_program(campaign, *, trials=None, workers=None, scheduler=None, start=PAPER_MANUAL, parameters=None,
                     max_iterations=10):
    """The program fit on the chosen trials, then the uncertainty of its result."""
    chosen = choose_trials(campaign, trials)
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        residuals = CampaignResiduals(chosen, executor=executor)
        result = fit_program(residuals, start=start, parameters=parameters, max_iterations=max_iterations)
        spread = uncertainty(residuals, result.friction, parameters=parameters)
    return result, spread


def identify_equation_error(campaign, *, trials=None, start=PAPER_MANUAL, parameters=None, effects=None, seed=0):
    """The equation-error fit (equation_error.py) on the chosen trials: no simulation."""
    from .equation_error import fit_equation_error

    return fit_equation_error(choose_trials(campaign, trials), start=start, parameters=parameters, effects=effects,
                              seed=seed)


def seeded_start(campaign, *, trials=None, start=PAPER_MANUAL, parameters=None) -> tuple:
    """`start` with the coefficients that equation error identifies from the chosen trials replaced by its
    estimates (no simulation): (start, EquationErrorResult or None when no trial has a camera)."""
    from .equation_error import fit_equation_error, sees_whole_configuration

    chosen = choose_trials(campaign, trials)
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
    estimation = choose_trials(campaign, trials)
    if validation is None:
        return estimation, [t for t in campaign.trials if t not in estimation]
    held = choose_trials(campaign, validation)
    overlap = sorted({t.trial_id for t in held} & {t.trial_id for t in estimation})
    if overlap:
        raise Rc1Error(f"{campaign.path}: trial '{overlap[0]}' is both an estimation and a validation trial")
    return estimation, held


def held_out_errors(estimation, validation, friction: Friction, *, workers=None, scheduler=None) -> HeldOut:
    """Eq. 6 errors of `friction` on the estimation trials and on the validation trials (split_trials)."""
    everything = estimation + validation
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(everything)), scheduler=scheduler) as executor:
        errors = Eq6Objective(everything, executor=executor).per_trial(friction)
    k = len(estimation)
    return HeldOut(estimation_trials=[t.trial_id for t in estimation],
                   validation_trials=[t.trial_id for t in validation],
                   estimation_error_pct=float(np.mean(errors[:k])),
                   validation_error_pct=float(np.mean(errors[k:])) if validation else None,
                   simulations=len(everything))
