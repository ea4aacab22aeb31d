"""A fit judged on trials it was not fitted to: the estimation and validation split, and their Eq. 6 errors."""

import dataclasses
import os

import numpy as np

from ..config import Friction, Rc1Error
from ..executor import make_executor
from .avs import Eq6Objective


@dataclasses.dataclass
class HeldOut:
    """Mean Eq. 6 error (%) of the result on the trials it was fitted to and on held-out trials."""

    estimation_trials: list[str]
    validation_trials: list[str]
    estimation_error_pct: float
    validation_error_pct: float | None  # None without held-out trials
    simulations: int

    def line(self) -> str:
        held = (
            "no held-out trials"
            if self.validation_error_pct is None
            else f"held-out {self.validation_error_pct:.2f}% ({len(self.validation_trials)} trials)"
        )
        return (
            f"mean Eq. 6 error: estimation {self.estimation_error_pct:.2f}% ({len(self.estimation_trials)} trials), "
            f"{held}"
        )


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


def held_out_errors(
    estimation, validation, friction: Friction, *, workers=None, scheduler=None, effects=None, checkpoint=None
) -> HeldOut:
    """Eq. 6 errors of `friction` (and `effects`) on the estimation and the validation trials (split_trials)."""
    everything = estimation + validation
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(everything)), scheduler=scheduler) as executor:
        errors = Eq6Objective(everything, executor=executor, effects=effects, checkpoint=checkpoint).per_trial(friction)
    k = len(estimation)
    return HeldOut(
        estimation_trials=[t.trial_id for t in estimation],
        validation_trials=[t.trial_id for t in validation],
        estimation_error_pct=float(np.mean(errors[:k])),
        validation_error_pct=float(np.mean(errors[k:])) if validation else None,
        simulations=len(everything),
    )
