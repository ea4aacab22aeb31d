"""The diagnosis's replays: one trial scored at a model (its standardized residuals, Eq. 6, yaw-rate fit, its end,
its start rows); the replay's own error is sysid.input_noise's twin bootstrap."""

import numpy as np

from ..compare import fit_percent, score_trial, simulator_error
from ..start import START_FIT_S, start_residual
from ..sysid.evaluate import replay
from ..sysid.residual import trial_residual

INPUT_NOISE_SAMPLES = 6  # bootstrap replays per trial for the replay's bias and input noise (replay_error)


def evaluate(trial, friction, effects) -> tuple:
    """One replay, scored: (standardized residuals, Eq. 6 error %, yaw-rate fit %, the standardized residuals of
    its first START_FIT_S at the full sampling rate: start.start_residual)."""
    run = replay(trial, friction, effects)
    t = trial.t - trial.t[0]
    inside = t <= run.t[-1] + 1e-9
    fit = fit_percent(trial.head_yaw_rate[inside], np.interp(t[inside], run.t, run.head_yaw_rate))
    return (
        trial_residual(trial, run),
        simulator_error(run.final_head_xy, trial.final_head_xy, trial.initial_head_pose[:2]),
        fit,
        start_residual(trial, run, START_FIT_S),
    )


def replay_and_score(trial, friction, effects) -> tuple:
    run = replay(trial, friction, effects)
    return score_trial(trial, run), run
