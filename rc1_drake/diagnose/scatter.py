"""The failed joint's scatter, a variance component of the final positions (beside significance's noise).

Another model's failed joint swings differently from trial to trial, and its misses share no law: fitting the
failed joint's constant torque, centring spring and viscous torque shared by a campaign's trials trades one trial
held out for another (docs/findings.md, 2026-11-28). So each failed-joint trial's residuals get, beside the hand
noise and the input noise, tau^2 X X^T: X their columns by those three terms (discrepancy.py's failed-joint terms, per
probe step), as if each trial drew its own terms with a standard deviation of tau probe steps; tau one scale per
campaign, by maximum likelihood on the final positions at the model the misfit is judged at, taken in the misfit test
and the trials' weights. Taken only up to Thresholds.max_failed_joint_scatter, the largest scatter the models'
differences were measured to make: beyond it the failed joints' trials show a law, not a scatter (a failed joint's dry
friction, a working joint's potentiometer offset), and none is taken. An effect that shows only in the failed joints
within that bound is taken as scatter."""

import dataclasses
import math

import numpy as np
from scipy.optimize import minimize_scalar

from .coordinates import effect_coordinates, model_at, signed_step
from .linearize import trial_weights
from .replays import evaluate

TERMS = tuple(f"discrepancy_failed_joint_{kind}" for kind in ("bias", "spring", "drag"))


@dataclasses.dataclass
class Scatter:
    """Per trial, its residuals' columns (rows x len(TERMS), standardized, per probe step of each term; the final
    position's first) by the failed joint's terms, or None for a trial without a failed joint."""

    columns: list

    def covariances(self, variances: list[float], tau: float) -> list[np.ndarray]:
        """Per trial, its final position's covariance: variance * I plus tau^2 X X^T where it has a failed joint."""
        return [
            v * np.eye(2) + (0.0 if x is None else tau * tau * x[:2] @ x[:2].T)
            for v, x in zip(variances, self.columns, strict=True)
        ]

    def weighing(self, lin, tau: float):
        """`lin` with its trials weighed by the scatter tau too: its variance per row (the mean of tau^2 X X^T's
        diagonal over the trial's rows) beside the input noise's (linearize.trial_weights)."""
        scatter = [0.0 if x is None else tau * tau * float(np.mean(np.sum(x * x, axis=1))) for x in self.columns]
        return dataclasses.replace(lin, scatter=scatter, weights=trial_weights(lin.trials, lin.noise, scatter))

    def scale(self, residual: list[np.ndarray], variances: list[float], bound: float) -> tuple[float, float]:
        """(tau taken: the maximum-likelihood scale of the failed-joint trials' final positions `residual` given their
        noise `variances` where it is at most `bound`, else 0; that scale). 0 where no trial has a failed joint."""
        failed = [(r[:2], v, x[:2]) for r, v, x in zip(residual, variances, self.columns, strict=True) if x is not None]
        if not failed or bound <= 0:
            return 0.0, 0.0

        def nll(tau: float) -> float:
            total = 0.0
            for r, v, x in failed:
                c = v * np.eye(2) + tau * tau * x @ x.T
                total += float(r @ np.linalg.solve(c, r)) + float(np.linalg.slogdet(c)[1])
            return 0.5 * total

        upper = _largest_scale(failed)
        inner = minimize_scalar(
            lambda s: nll(math.exp(s)), bounds=(math.log(1e-6 * upper), math.log(upper)), method="bounded"
        )
        unbounded = min((0.0, math.exp(float(inner.x))), key=nll)
        return (unbounded if unbounded <= bound else 0.0), unbounded


def _largest_scale(failed) -> float:
    """A scale past which the likelihood only falls: where tau^2 X X^T's weakest direction holds the largest
    residual a hundred times over."""
    weakest = [
        s[s > 1e-12 * s.max()].min() for s in (np.linalg.svd(x, compute_uv=False) for _, _, x in failed) if s.max() > 0
    ]
    return 100.0 * max(float(math.sqrt(r @ r + v)) for r, v, _ in failed) / float(min(weakest or [1.0]))


def failed_joint_scatter(lin, evaluator) -> Scatter:
    """The failed-joint trials' columns by TERMS at `lin`'s model (forward differences: one replay a term and
    failed-joint trial; the terms are never fitted, so these columns stay the start's)."""
    coords = [c for name in TERMS for c in effect_coordinates(name, lin.effects)]
    failed = [k for k, t in enumerate(lin.trials) if t.failed_joints]
    jobs = []
    for c in coords:
        model = model_at(lin.friction, lin.effects, [c], [c.value + signed_step(c)])
        jobs += [(lin.trials[k], *model) for k in failed]
    out = iter(evaluator.map(evaluate, jobs, "the failed joint's scatter: its columns"))
    columns = [np.zeros((len(lin.r0[k]), len(coords))) if k in failed else None for k in range(len(lin.trials))]
    for j, c in enumerate(coords):
        per_step = c.step / signed_step(c)
        for k in failed:
            columns[k][:, j] = per_step * (lin.corrected(k, next(out)[0]) - lin.r0[k])
    return Scatter(columns)
