"""The replays' own error: a replay follows noisy measured angles, so its residuals scatter with that noise whatever
the model, and its start and smoothing bias them. Two estimates: the covariance from replays of the trial with its
angle noise resampled (identify: Replayer.run_resampled), and the bias and covariance from a parametric bootstrap on
the trial's noise-free twin (diagnose: replay_error)."""

import dataclasses

import numpy as np

from ..config import Friction
from ..engine import default_engine
from ..replay import Replayer
from ..start import START_FIT_S, start_residual
from ..synthesize import noise_free_twin
from .evaluate import replayer
from .residual import trial_residual

# Resampled replays per trial for the input-noise part of every interval (uncertainty()).
INPUT_NOISE_SAMPLES = 8


def input_noise_covariance(trial, friction: Friction, effects, samples: int, seed: int) -> np.ndarray:
    """Covariance of one trial's residuals over `samples` replays with resampled angle noise."""
    own, rng = replayer(trial), np.random.default_rng(seed)
    draws = np.array([trial_residual(trial, own.run_resampled(friction, effects, rng)) for _ in range(samples)])
    if len(draws) < 2:
        return np.zeros((draws.shape[-1],) * 2)  # too few draws for a covariance (none: an empty block)
    deviation = draws - draws.mean(axis=0)
    return deviation.T @ deviation / (len(draws) - 1)


def replay_error(trial, friction, effects, samples: int, seed: int) -> tuple:
    """What replaying this trial gets wrong, by a parametric bootstrap on its noise-free twin
    (synthesize.noise_free_twin, made by the model): `samples` draws of the trial's potentiometer noise
    (as its smoothing estimates it: Replayer.angle_noise_rad) on the twin's angles, each replayed at the model and
    scored against the twin, whose residuals have the trial's entries (sysid.residual.trial_residual). Returns
    (bias, covariance): the draws' mean residual — the replay's own miss on this motion, from its start state, its
    smoothing of noisy angles and its stiff servos (measured on 3 s no-failure trials: the noise alone shifts the
    start transient by what a 0.3 deg toe would, trial after trial) — and their covariance (the input noise; a
    joint-2 failure, which circles, replays chaotically: there it is large). (In this process; replay_errors
    spreads the twins and the draws over an executor, with the same result.)"""
    made = bootstrap_twin(trial, friction, effects)
    return draws_mean_and_covariance([bootstrap_draw(*made, friction, effects, seed, i) for i in range(samples)])[:2]


def bootstrap_twin(trial, friction, effects, servo=None) -> tuple:
    """replay_error's twin (the model's servos `servo`, default config.Servo()), with the trial's camera misses, and
    the trial's angle noise (rad)."""
    twin = noise_free_twin(trial, friction=friction, effects=effects, servo=servo)
    if trial.initial_head_rates is None:  # replayed from the convention, as the trial is
        twin = dataclasses.replace(twin, initial_head_rates=None)
    camera = None
    if trial.camera is not None:
        camera = twin.camera.copy()
        camera[np.isnan(trial.camera[:, 0])] = np.nan
    return dataclasses.replace(twin, camera=camera), replayer(trial).angle_noise_rad()


_TWIN_REPLAYERS: dict = {}  # per worker process: a twin (its id and angles) -> its Replayer, the last few only


def bootstrap_draw(twin, sigma_rad: float, friction, effects, seed: int, index: int) -> tuple:
    """Draw `index` of replay_error: the twin replayed at the model from its angles plus the `index`-th noise
    draw of the stream `seed` (so that draws split over processes are the ones one process would make); its
    residuals, and those of its start rows (start.start_residual)."""
    key = (default_engine(), twin.trial_id, twin.q.tobytes())
    if key not in _TWIN_REPLAYERS:
        if len(_TWIN_REPLAYERS) >= 8:
            _TWIN_REPLAYERS.pop(next(iter(_TWIN_REPLAYERS)))
        _TWIN_REPLAYERS[key] = Replayer(twin)
    replayer, rng = _TWIN_REPLAYERS[key], np.random.default_rng(seed)
    for _ in range(index):
        replayer.angle_noise(rng, sigma_rad)
    angles = twin.q + replayer.angle_noise(rng, sigma_rad)
    run = replayer.run_with_angles(friction, effects, angles)
    return trial_residual(twin, run), start_residual(twin, run, START_FIT_S)


def draws_mean_and_covariance(draws) -> tuple:
    """(mean, covariance) of the draws' residuals, and the mean of their start rows'."""
    residuals = np.array([d[0] for d in draws])
    deviation = residuals - residuals.mean(axis=0)
    start = np.mean([d[1] for d in draws], axis=0)
    return residuals.mean(axis=0), deviation.T @ deviation / max(len(draws) - 1, 1), start
