"""Find the missing physics: fit today's model, see where it fails, rank the candidate effects
(rc1_drake/effects/) on held-out trials, accept one only when it is significant and holds on trials it was not
fitted to, add it, and repeat until nothing more is found; the waterfall shows what each step bought.

The method, linearized where that is safe and checked by simulation where it decides:

1. Linearize. At the current model, the stacked standardized residuals r0 of every trial's replay
   (sysid.residual.trial_residual: final position, camera path or yaw rate) and their Jacobian by forward
   differences: one column per friction coefficient, one per candidate coordinate at its probe step
   (a small, clearly visible strength: EffectParameter.probe). What the replay itself gets wrong is
   taken once, by a parametric bootstrap on each trial's noise-free twin (replays.replay_error): its mean is
   subtracted from every residual of that trial (the replay's bias), its covariance is the input noise.
2. Fit. For today's model (the friction coefficients these data identify, identify.screen's rule) and
   for it plus each candidate: the bounded least squares of r0 + J d (a Drake MathematicalProgram), the
   parameters' sandwich covariance with the input noise, their Wald test against 0 (the nested value),
   the leave-one-trial-out held-out error of the linear model, and AIC.
3. Decide. The candidate with the largest held-out reduction among the significant ones is checked by
   simulation: every trial replayed with the parameters fitted without it, for today's model and for the
   candidate. It is accepted only when it is significant (Wald p below Thresholds.p_accept) and the simulated
   held-out error falls by Thresholds.accept_held_out_reduction (half) at least; one that lowers it by less (but by
   Thresholds.min_held_out_reduction at least) explains part of it, and is reported, not accepted. Candidates whose
   columns, after the friction's are projected out, are nearly parallel (cosine above
   Thresholds.indistinguishable_cos) cannot be told apart by these data; an effect whose largest physical value
   would not be significant here is "not detectable here", and the probe study (probe.probe_visibility) names
   the kind of trial that would see it.
4. Repeat at the new model while what is left is not consistent with the noise: its residuals are
   simulated again, the Jacobian's columns updated by Broyden's secant update along the step (no new
   replays), the replay's own error measured again there (it depends on the model), the accepted model
   estimated further by Gauss-Newton steps (fit.polish: the decision was taken at a bounded fit), today's parameters
   (friction, accepted effects) refitted and moved where simulation confirms it, and the remaining
   candidates ranked there.

The verdict: `effect_found` when effects were accepted and what is left is consistent with the noise (the
final positions' chi-squared with the hand and input noise, the replay's bias taken off);
`no_missing_effect` when nothing was accepted and the misfit is consistent with the noise; `ambiguous`
when two candidates explain the held-out trials alike (the runner-up's simulated held-out sum of squares
within Thresholds.ambiguous_ratio of the best's), with the kind of trial that would tell them apart; `unexplained`
when a misfit remains that no candidate explains, or that a candidate explains only in part (any accepted
effects, and a candidate that helped by less than half, are then reported as partial).

The stages, a module each: coordinates (what is fitted), replays (a trial scored at a model; the replay's own
error), linearize, fit, significance (intervals, the Wald test, the misfit), decide (rank, check, decide),
verdict, report (what is returned), probe (the probe study), loop (diagnose itself); thresholds holds every
threshold the decisions use, with its reason.
"""

from ..sysid.input_noise import replay_error
from .loop import MAX_ROUNDS, diagnose
from .probe import probe_visibility
from .replays import INPUT_NOISE_SAMPLES
from .report import Diagnosis
from .thresholds import THRESHOLDS, Thresholds
from .verdict import Verdict

__all__ = [
    "INPUT_NOISE_SAMPLES",
    "MAX_ROUNDS",
    "THRESHOLDS",
    "Diagnosis",
    "Thresholds",
    "Verdict",
    "diagnose",
    "probe_visibility",
    "replay_error",
]
