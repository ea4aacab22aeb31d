"""What a fit's numbers mean: intervals, the Wald test of a candidate against its nested value, the final
positions' misfit against the noise, and how far apart two candidates' columns are."""

import dataclasses
import math

import numpy as np
from scipy.stats import chi2

from .linearize import FINAL_SIGMA_M, Linearization, pooled_per_case
from .thresholds import THRESHOLDS, Thresholds


def _final_position_variances(lin: Linearization) -> dict[str, float]:
    """Per case: the final position's variance per axis, standardized (hand noise 1 plus the input noise,
    pooled per case: one trial's few bootstrap replays estimate a variance too loosely)."""
    pooled = pooled_per_case(lin.trials, [float(np.mean(np.diag(noise)[:2])) for noise in lin.noise])
    return {case: 1.0 + v for case, v in pooled.items()}


def final_misfit(lin: Linearization, residual: list[np.ndarray], free: int, exclude=()) -> tuple:
    """(chi-squared, dof, p) of the final positions of the trials not in `exclude` (ids) against the hand
    noise (RESIDUAL_SIGMAS, 1 in standardized units) plus the input noise."""

    variance = _final_position_variances(lin)
    kept = [(t, r) for t, r in zip(lin.trials, residual, strict=True) if t.trial_id not in exclude]
    stat = float(sum(float(r[:2] @ r[:2]) / variance[t.case] for t, r in kept))
    dof = max(2 * len(kept) - free, 1)
    return stat, dof, float(chi2.sf(stat, dof))


@dataclasses.dataclass
class Misfit:
    """What a model leaves in the final positions: the campaign's p-value without the outlying trials,
    and those trials (each far beyond the noise on its own: p below Thresholds.p_misfit / trials)."""

    p: float
    outliers: dict[str, dict]  # trial -> {"off_cm", "noise_cm", "p"}
    p_threshold: float = THRESHOLDS.p_misfit  # consistent with the noise above it

    @property
    def consistent(self) -> bool:
        return self.p > self.p_threshold


def misfit(lin: Linearization, residual: list[np.ndarray], free: int, thresholds: Thresholds = THRESHOLDS) -> Misfit:

    variance = _final_position_variances(lin)
    outliers = {}
    for t, r in zip(lin.trials, residual, strict=True):
        p = float(chi2.sf(float(r[:2] @ r[:2]) / variance[t.case], 2))
        if p < thresholds.p_misfit / len(lin.trials):
            outliers[t.trial_id] = {
                "off_cm": 100 * FINAL_SIGMA_M * float(np.linalg.norm(r[:2])),
                "noise_cm": 100 * FINAL_SIGMA_M * math.sqrt(variance[t.case]),
                "p": p,
            }
    if len(outliers) > thresholds.max_outlier_fraction * len(lin.trials):
        return Misfit(final_misfit(lin, residual, free)[2], outliers, thresholds.p_misfit)
    return Misfit(final_misfit(lin, residual, free, exclude=outliers)[2], outliers, thresholds.p_misfit)


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
