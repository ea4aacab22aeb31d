"""The diagnosis's replays: one trial scored at a model (its standardized residuals, Eq. 6, yaw-rate fit, its end,
its start rows); the replay's own error is sysid.input_noise's twin bootstrap."""

import numpy as np

from ..compare import fit_percent, score_trial, simulator_error
from ..start import START_FIT_S, start_residual
from ..sysid.evaluate import replay, replayer
from ..sysid.residual import trial_residual

INPUT_NOISE_SAMPLES = 6  # bootstrap replays per trial for the replay's bias and input noise (replay_error)


def evaluate(trial, friction, effects) -> tuple:
    """One replay, scored: (standardized residuals, Eq. 6 error %, yaw-rate fit %, the standardized residuals of
    its first START_FIT_S at the full sampling rate: start.start_residual)."""
    return _scored(trial, replay(trial, friction, effects))


def evaluate_with_tangent(trial, friction, effects, names) -> tuple:
    """(evaluate's tuple, d residuals / d name, d start residuals / d name): one replay with the compiled engine's
    exact sensitivities to `names` (engine.session.sensitivity_parameters), both residuals linear in its logs."""
    run = replayer(trial).run(friction, effects, sensitivities=tuple(names))
    scored = _scored(trial, run)
    return (
        scored,
        run.residual_jacobian(lambda moved: trial_residual(trial, moved), scored[0]),
        run.residual_jacobian(lambda moved: start_residual(trial, moved, START_FIT_S), scored[3]),
    )


def _scored(trial, run) -> tuple:
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
