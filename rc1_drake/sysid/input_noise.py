"""The replays' input noise: a replay follows noisy measured angles, so its residuals scatter with that noise
whatever the model. Its covariance, from replays with the angle noise resampled (Replayer.run_resampled)."""

import numpy as np

from ..config import Friction
from .evaluate import replayer
from .residual import trial_residual

# Resampled replays per trial for the input-noise part of every interval (uncertainty()).
INPUT_NOISE_SAMPLES = 8


def input_noise_covariance(trial, friction: Friction, effects, samples: int, seed: int, length=None) -> np.ndarray:
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
