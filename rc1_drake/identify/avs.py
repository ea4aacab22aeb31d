"""The paper's Alternating Variable Search (AVS, section 4, Table 1): start from the manual values, vary one
coefficient at a time over a bounded set of candidates, keep the best, move on to the next coefficient, for a
chosen number of iterations. Keeping the incumbent among the candidates makes the error non-increasing from
one iteration to the next. The objective is the mean paper Eq. 6 error of the trials' replays.
"""

import dataclasses
import math
import os

import numpy as np

from ..compare import simulator_error
from ..config import FRICTION_NAMES, Friction, Rc1Error
from ..executor import make_executor
from ..sysid.evaluate import Evaluator, replay
from ..sysid.input_noise import INPUT_NOISE_SAMPLES
from ..sysid.objective import CampaignResiduals
from ..sysid.parameters import DEFAULT_PARAMETERS, PAPER_MANUAL, Parameter, with_fixed
from ..sysid.stats import uncertainty


def eq6_error(trial, friction: Friction, effects=None) -> float:
    run = replay(trial, friction, effects)
    return simulator_error(run.final_head_xy, trial.final_head_xy, trial.initial_head_pose[:2])


class Eq6Objective:
    """Mean Eq. 6 error of the trials for a friction set; counts simulations, caches evaluations (and keeps
    each replay's in `checkpoint`, evaluate.Checkpoint, when given)."""

    def __init__(self, trials, *, executor=None, effects=None, checkpoint=None):
        self.trials = list(trials)
        self.evaluator = Evaluator(executor, checkpoint=checkpoint)
        self.effects = effects
        self.simulations = 0
        self._cache: dict[tuple, float] = {}

    def per_trial(self, friction: Friction, effects=None) -> list[float]:
        jobs = [(t, friction, with_fixed(self.effects, effects)) for t in self.trials]
        errors = self.evaluator.map(eq6_error, jobs, "Eq. 6 errors")
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
    candidates: list[float]
    errors: list[float]  # mean Eq. 6 error at each candidate
    best: float
    friction: Friction  # the set after this iteration
    error: float  # its mean Eq. 6 error


@dataclasses.dataclass
class AvsResult:
    start: Friction
    start_error: float
    iterations: list[AvsIteration]
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
                for it in self.iterations
            )
            lines.append(f"{name:<9}{getattr(self.start, name):>9.4g}{cells}")
        lines.append(f"{'Eq.6 %':<9}{self.start_error:>9.2f}" + "".join(f"{it.error:>9.2f}" for it in self.iterations))
        return "\n".join(lines)

    def to_json(self) -> dict:
        return {
            "method": "avs",
            "start": dataclasses.asdict(self.start),
            "start_error_pct": self.start_error,
            "friction": dataclasses.asdict(self.friction),
            "error_pct": self.error,
            "simulations": self.simulations,
            "iterations": [
                {**dataclasses.asdict(it), "friction": dataclasses.asdict(it.friction)} for it in self.iterations
            ],
        }


def avs_candidates(value: float, parameter: Parameter, factors=(0.5, 0.75, 1.25, 1.5)) -> list[float]:
    """Candidates around the incumbent, within the bounds (the incumbent itself is always kept)."""
    base = value if value > 0 else 0.1 * (parameter.upper - parameter.lower)
    out = {min(max(base * f, parameter.lower), parameter.upper) for f in factors}
    out.discard(value)
    return sorted(out)


def avs(
    objective,
    *,
    start: Friction = PAPER_MANUAL,
    iterations: int = 10,
    parameters: list[Parameter] | None = None,
    factors=(0.5, 0.75, 1.25, 1.5),
    progress=None,
) -> AvsResult:
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
        errors = [current_error] + [
            objective(dataclasses.replace(current, **{parameter.name: c})) for c in candidates[1:]
        ]
        best = int(np.argmin(errors))
        current = dataclasses.replace(current, **{parameter.name: candidates[best]})
        current_error = errors[best]
        order = np.argsort(candidates)
        history.append(
            AvsIteration(
                iteration=k + 1,
                parameter=parameter.name,
                candidates=[candidates[i] for i in order],
                errors=[errors[i] for i in order],
                best=candidates[best],
                friction=current,
                error=current_error,
            )
        )
        if progress:
            progress(k + 1, iterations, parameter.name, current_error)
    return AvsResult(
        start=start, start_error=start_error, iterations=history, simulations=getattr(objective, "simulations", 0)
    )


def identify_avs(
    campaign,
    *,
    trials=None,
    iterations=10,
    workers=None,
    scheduler=None,
    start=PAPER_MANUAL,
    parameters=None,
    progress=None,
    effects=None,
    input_noise_samples=INPUT_NOISE_SAMPLES,
    checkpoint=None,
    on_fit=None,
):
    """AVS on the chosen trials (the model with `effects`, held fixed), then the uncertainty of its
    result (uncertainty(), with `input_noise_samples`): (AvsResult, Uncertainty). `checkpoint`: an
    evaluate.Checkpoint that keeps every replay's result (a rerun resumes). `on_fit(result)`: called as the search
    ends, before the uncertainty (so that a caller keeps the fit whatever follows)."""
    chosen = campaign.chosen(trials)
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        objective = Eq6Objective(chosen, executor=executor, effects=effects, checkpoint=checkpoint)
        result = avs(objective, start=start, iterations=iterations, parameters=parameters, progress=progress)
        if on_fit:
            on_fit(result)
        residuals = CampaignResiduals(chosen, executor=executor, effects=effects, checkpoint=checkpoint)
        spread = uncertainty(residuals, result.friction, parameters=parameters, input_noise_samples=input_noise_samples)
    return result, spread


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
