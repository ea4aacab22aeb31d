"""What a fit's numbers mean: intervals, the Wald test of a candidate against its nested value, the final
positions' misfit against the noise, and how far apart two candidates' columns are."""

import dataclasses
import math

import numpy as np
from scipy.stats import chi2

from .linearize import FINAL_SIGMA_M, Linearization, pooled_per_case
from .scatter import Scatter
from .thresholds import THRESHOLDS, Thresholds


def _final_position_variances(lin: Linearization) -> list[float]:
    """Per trial: its final position's variance per axis, standardized (hand noise 1 plus the input noise,
    pooled per case: one trial's few bootstrap replays estimate a variance too loosely)."""
    pooled = pooled_per_case(lin.trials, [float(np.mean(np.diag(noise)[:2])) for noise in lin.noise])
    return [1.0 + pooled[t.case] for t in lin.trials]


def final_covariances(lin: Linearization, residual, scatter: Scatter | None = None, bound: float = 0.0) -> tuple:
    """(per trial, its final position's 2 x 2 covariance, standardized; the failed joint's scatter tau taken in it
    (none beyond `bound`: Scatter.scale); its maximum-likelihood value): the noise (_final_position_variances), plus
    the failed joint's scatter where `scatter` is given (scatter.py)."""
    variances = _final_position_variances(lin)
    if scatter is None:
        return [v * np.eye(2) for v in variances], 0.0, 0.0
    tau, unbounded = scatter.scale(residual, variances, bound)
    return scatter.covariances(variances, tau), tau, unbounded


def _standardized(r: np.ndarray, covariance: np.ndarray) -> float:
    return float(r[:2] @ np.linalg.solve(covariance, r[:2]))


def final_misfit(lin: Linearization, residual: list[np.ndarray], free: int, exclude=(), covariances=None) -> tuple:
    """(chi-squared, dof, p) of the final positions of the trials not in `exclude` (ids) against the hand
    noise (RESIDUAL_SIGMAS, 1 in standardized units) plus the input noise (or `covariances`, per trial)."""
    covariances = covariances or final_covariances(lin, residual)[0]
    kept = [(r, c) for t, r, c in zip(lin.trials, residual, covariances, strict=True) if t.trial_id not in exclude]
    stat = float(sum(_standardized(r, c) for r, c in kept))
    dof = max(2 * len(kept) - free, 1)
    return stat, dof, float(chi2.sf(stat, dof))


@dataclasses.dataclass
class Misfit:
    """What a model leaves in the final positions: the campaign's p-value without the outlying trials,
    and those trials (each far beyond the noise on its own: p below Thresholds.p_misfit / trials)."""

    p: float
    outliers: dict[str, dict]  # trial -> {"off_cm", "noise_cm", "p"}
    p_threshold: float = THRESHOLDS.p_misfit  # consistent with the noise above it
    scatter: float = 0.0  # the failed joint's scatter taken as noise (tau, probe steps; scatter.py)
    scatter_unbounded: float = 0.0  # its maximum-likelihood value, taken or not (Thresholds.max_failed_joint_scatter)

    @property
    def consistent(self) -> bool:
        return self.p > self.p_threshold


def misfit(
    lin: Linearization, residual: list[np.ndarray], free: int, thresholds: Thresholds = THRESHOLDS, scatter=None
) -> Misfit:
    """The Misfit of `residual` (per trial, standardized) for a model of `free` parameters; with `scatter`
    (scatter.py), the failed joint's scatter up to Thresholds.max_failed_joint_scatter taken as noise (one more
    parameter where it is taken)."""
    covariances, tau, unbounded = final_covariances(lin, residual, scatter, thresholds.max_failed_joint_scatter)
    free += tau > 0
    outliers = {}
    for t, r, c in zip(lin.trials, residual, covariances, strict=True):
        p = float(chi2.sf(_standardized(r, c), 2))
        if p < thresholds.p_misfit / len(lin.trials):
            outliers[t.trial_id] = {
                "off_cm": 100 * FINAL_SIGMA_M * float(np.linalg.norm(r[:2])),
                "noise_cm": 100 * FINAL_SIGMA_M * math.sqrt(float(np.trace(c)) / 2),
                "p": p,
            }
    exclude = () if len(outliers) > thresholds.max_outlier_fraction * len(lin.trials) else outliers
    p = final_misfit(lin, residual, free, exclude=exclude, covariances=covariances)[2]
    return Misfit(p, outliers, thresholds.p_misfit, tau, unbounded)


def orthogonal_to(x, basis) -> np.ndarray:
    if basis.shape[1] == 0:
        return x
    q, _ = np.linalg.qr(basis)
    return x - q @ (q.T @ x)


def subspace_cosine(a, b) -> float:
    """Cosine of the smallest angle between the column spaces of a and b."""
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False).max())
