"""The objective of a least-squares fit: the stacked standardized residuals of a campaign's replays at a model,
their exact Jacobian where the compiled engine gives sensitivities, and the input noise's covariance."""

import numpy as np
from scipy.linalg import block_diag

from ..config import Friction
from .evaluate import Evaluator
from .input_noise import INPUT_NOISE_SAMPLES, input_noise_covariance
from .parameters import with_fixed
from .residual import replay_residual, replay_residual_and_jacobian, residual_channels


class CampaignResiduals:
    """The stacked standardized residuals of the trials for a friction set (and effect parameters, set
    over the fixed `effects` given here); counts simulations. Replays run on `executor` (this process when None),
    their results kept in `checkpoint` (evaluate.Checkpoint) when given."""

    def __init__(self, trials, *, executor=None, effects=None, checkpoint=None):
        self.trials, self.effects = list(trials), effects
        self.evaluator = Evaluator(executor, checkpoint=checkpoint)
        self.simulations = 0

    def __call__(self, friction: Friction, effects=None) -> np.ndarray:
        jobs = [(t, friction, with_fixed(self.effects, effects)) for t in self.trials]
        parts = self.evaluator.map(replay_residual, jobs, "residuals")
        self.simulations += len(self.trials)
        self.channels = np.concatenate([residual_channels(p) for p in parts])
        self._group(parts)
        return np.concatenate(parts)

    def with_jacobian(self, friction: Friction, effects, names) -> tuple:
        """(the stacked residuals, their derivatives by the parameters `names`) from one replay per trial
        (exact_jacobian_available(names) must hold)."""
        jobs = [(t, friction, with_fixed(self.effects, effects), tuple(names)) for t in self.trials]
        parts = self.evaluator.map(replay_residual_and_jacobian, jobs, "residuals and their Jacobian")
        self.simulations += len(self.trials)
        self.channels = np.concatenate([residual_channels(r) for r, _ in parts])
        self._group([r for r, _ in parts])
        return np.concatenate([r for r, _ in parts]), np.vstack([j for _, j in parts])

    def _group(self, parts) -> None:
        """Each stacked row's trial (`groups`) and its trial's failed joints (`failure_groups`: one label per set of
        failed joints, the bias aside), for the jackknives of stats.uncertainty."""
        failed = {tuple(t.failed_joints) for t in self.trials}
        label = {f: k for k, f in enumerate(sorted(failed))}
        self.groups = np.concatenate([np.full(len(p), k) for k, p in enumerate(parts)])
        self.failure_groups = np.concatenate(
            [np.full(len(p), label[tuple(t.failed_joints)]) for t, p in zip(self.trials, parts, strict=True)]
        )

    def input_noise(
        self, friction: Friction, effects=None, *, samples: int = INPUT_NOISE_SAMPLES, seed: int = 0
    ) -> np.ndarray:
        """Block-diagonal covariance of the stacked residuals that the angle noise in the replays' input
        causes, from `samples` resampled replays per trial."""
        jobs = [(t, friction, with_fixed(self.effects, effects), samples, seed + k) for k, t in enumerate(self.trials)]
        blocks = self.evaluator.map(input_noise_covariance, jobs, "input noise")
        self.simulations += samples * len(self.trials)
        return block_diag(*blocks)
