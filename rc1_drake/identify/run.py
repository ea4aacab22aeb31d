"""One identification as `rc1 identify` runs it: the method, its start (the paper's manual values, a model file,
or equation error's estimates for the program fit), the trials' starts where asked, the fit, its uncertainty,
and its errors on held-out trials."""

import dataclasses
import time
from collections.abc import Callable

from ..config import START_MODES, Friction
from ..replay import fit_starts
from ..scenarios import ModelFile
from ..start import START_NAMES
from ..sysid.evaluate import Checkpoint
from ..sysid.input_noise import INPUT_NOISE_SAMPLES
from ..sysid.parameters import DEFAULT_PARAMETERS, PAPER_MANUAL
from ..sysid.stats import Uncertainty
from .avs import identify_avs
from .heldout import HeldOut, held_out_errors, split_trials
from .program import identify_equation_error, identify_program, seeded_start

METHODS = ("avs", "program", "equation-error")


@dataclasses.dataclass
class Identification:
    method: str
    result: object  # AvsResult, ProgramResult or EquationErrorResult: .friction, .table() where it has one
    uncertainty: Uncertainty | None  # at the result (AVS and program)
    warnings: list[str]
    held_out: HeldOut
    effects: dict | None  # the model's effects, held fixed
    simulations: int  # of the fit and its uncertainty
    wall_s: float  # of the fit and its uncertainty
    notes: list[str] = dataclasses.field(default_factory=list)  # how the start was chosen
    record: dict = dataclasses.field(default_factory=dict)  # the trials' fitted starts, equation error's start
    resumed: int = 0  # replays whose results came from the checkpoint of an interrupted run

    @property
    def friction(self) -> Friction:
        return self.result.friction

    def format(self) -> str:
        """The report `rc1 identify` prints."""
        r = self.result
        lines = list(self.notes)
        if self.method == "avs":
            lines += [
                "Friction identification by AVS (paper Table 1; * = the coefficient each iteration varied):",
                r.table(),
            ]
        elif self.method == "program":
            lines.append(
                f"Friction identification by least squares ({r.iterations} iterations, cost "
                f"{r.cost_start:.1f} -> {r.cost:.1f}):"
            )
        else:
            lines += [
                f"Friction identification by equation error (inverse dynamics, {r.wall_time_s:.0f} s, no simulation):",
                r.table(),
            ]
        if self.uncertainty is not None:
            lines += [
                "",
                f"Uncertainty at the result (residual Jacobian; standardized residual RMS "
                f"{self.uncertainty.residual_rms:.2f}):",
                self.uncertainty.table(),
            ]
        lines += [f"warning: {w}" for w in self.warnings]
        resumed = f" ({self.resumed} results from an interrupted run's checkpoint)" if self.resumed else ""
        lines += [
            self.held_out.line(),
            f"fit: {self.simulations} simulations, {self.wall_s:.0f} s; errors: "
            f"{self.held_out.simulations} more simulations{resumed}",
        ]
        return "\n".join(lines)

    def to_json(self) -> dict:
        return {
            **self.record,
            **self.result.to_json(),
            "uncertainty": dataclasses.asdict(self.uncertainty) if self.uncertainty else None,
            "warnings": self.warnings,
            "simulations": self.simulations,
            "wall_time_s": self.wall_s,
            "held_out": dataclasses.asdict(self.held_out),
        }


def identify(
    campaign,
    *,
    method: str = "avs",
    trials=None,
    validation=None,
    start: ModelFile | None = None,
    freeze=(),
    start_rates: str = "rest",
    iterations: int = 10,
    input_noise_samples: int = INPUT_NOISE_SAMPLES,
    workers=None,
    scheduler=None,
    progress: Callable | None = None,
    checkpoint=None,
    on_fit: Callable | None = None,
) -> Identification:
    """Identify the free friction coefficients of `campaign`'s `trials` (all by default) by `method`, from `start`
    (a model file: its coefficients and its effects, which stay fixed; the paper's manual values by default, where
    the program fit starts from what equation error identifies), with the coefficients in `freeze` held; judged on
    `validation` (by default the trials not fitted). `start_rates` "fit": each trial's start is fitted once to its
    first 0.5 s at the start model and held. `progress(done, total, name, error)`: each AVS iteration.
    `checkpoint`: a folder where every replay's result is kept as it arrives; run again with it, an interrupted
    identification resumes where it stopped (a fit that ended, from its end). `on_fit(result)`: called with the fit
    (AvsResult, ProgramResult, EquationErrorResult) as it ends, before its uncertainty and held-out errors."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if start_rates not in START_MODES:
        raise ValueError(f"start_rates must be one of {START_MODES}, got {start_rates!r}")
    split_trials(campaign, trials=trials, validation=validation)  # a bad id stops here, before any work
    parameters = [dataclasses.replace(p, frozen=p.name in freeze) for p in DEFAULT_PARAMETERS]
    friction = start.friction if start else PAPER_MANUAL
    effects = (start.effects if start else None) or None
    notes, record = [], {}
    if start_rates == "fit":
        campaign = fit_starts(campaign, friction=friction, effects=effects, workers=workers, scheduler=scheduler)
        record["starts"] = {
            t.trial_id: dict(zip(START_NAMES, map(float, t.initial_head_rates), strict=True)) for t in campaign.trials
        }
    estimation, held = split_trials(campaign, trials=trials, validation=validation)
    began = time.perf_counter()
    kept = Checkpoint(checkpoint) if checkpoint else None
    common = dict(trials=trials, parameters=parameters, start=friction, effects=effects)
    simulated = dict(
        workers=workers, scheduler=scheduler, input_noise_samples=input_noise_samples, checkpoint=kept, on_fit=on_fit
    )
    spread = None
    if method == "avs":
        result, spread = identify_avs(campaign, iterations=iterations, progress=progress, **common, **simulated)
    elif method == "program":
        if start is None:
            common["start"], seed = seeded_start(campaign, trials=trials, start=friction, parameters=parameters)
            if seed is not None:
                notes.append(_seed_note(seed))
                record["equation_error_start"] = seed.to_json()
        result, spread = identify_program(campaign, max_iterations=iterations, **common, **simulated)
    else:
        result = identify_equation_error(campaign, **common)
        if on_fit:
            on_fit(result)
    warnings = spread.warnings() if spread is not None else result.warnings()
    if method == "program" and result.held:
        warnings.append(held_warning(result.held, [p.name for p in parameters if not p.frozen]))
    simulations, wall = result.simulations + (spread.simulations if spread else 0), time.perf_counter() - began
    errors = held_out_errors(
        estimation, held, result.friction, workers=workers, scheduler=scheduler, effects=effects, checkpoint=kept
    )
    return Identification(
        method=method,
        result=result,
        uncertainty=spread,
        warnings=warnings,
        held_out=errors,
        effects=effects,
        simulations=simulations,
        wall_s=wall,
        notes=notes,
        record=record,
        resumed=kept.resumed if kept else 0,
    )


def _seed_note(seed) -> str:
    """The report's line on the program fit's start where equation error chose it (seeded_start)."""
    used = [n for n, ok in zip(seed.names, seed.identifiable, strict=True) if ok]
    return (
        f"start: equation error identified {', '.join(used) or 'nothing'} "
        f"({seed.wall_time_s:.0f} s, no simulation); the rest from the paper's manual values"
    )


def held_warning(held: list[str], free: list[str]) -> str:
    """The program fit's warning for the coefficients the start's screen held; where it held every free one, what
    to do: a start far from the data sees nothing (diagnose searches from it first: docs/diagnosis.md, step 2)."""
    text = f"held at the start values (not identifiable at the start): {', '.join(held)}"
    if not set(free) <= set(held):
        text += "; the fitted coefficients' intervals carry them, each known to a factor 2"
    else:
        text += (
            "; nothing was fitted: if the start's replays miss the data by far, the start may be far from them: "
            "`rc1 identify --method avs` searches from it, and its model file (--out) starts a program fit there "
            "(--start)"
        )
    return text
