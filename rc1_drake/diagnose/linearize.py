"""Linearize (stage 1): the standardized residuals of every trial at a model, their columns by each coordinate
(forward differences, then Broyden's secant updates as the model moves), and the replay's own error taken off."""

import dataclasses
import math

import numpy as np

from ..compare import simulator_error
from ..config import RESIDUAL_SIGMAS, Friction
from ..effects import active
from ..replay import with_start_guess
from ..sysid.evaluate import Evaluator
from ..sysid.input_noise import bootstrap_draw, bootstrap_twin, draws_mean_and_covariance
from ..sysid.parameters import Parameter
from ..sysid.residual import residual_channels
from .coordinates import (
    acts_in_failed_joints_only,
    coordinate_values,
    effect_coordinates,
    friction_coordinates,
    model_at,
    signed_step,
    start_coordinates,
    starts_at,
)
from .replays import INPUT_NOISE_SAMPLES, evaluate

FINAL_SIGMA_M = RESIDUAL_SIGMAS["final_m"]
# Draws a paired measurement of the replay's own error repeats (same noise as the full one's first draws): the bias
# moves by 1.6-4.9 standardized units on a J7 trial from the paper's model to a 2 deg toe or mu_lat -20%, and the
# paired difference of two draws follows it to 0.05-0.55, about the full six draws' own standard error (0.1-0.5).
PAIRED_DRAWS = 2


@dataclasses.dataclass
class Linearization:
    trials: list
    friction: Friction
    effects: dict[str, float]
    coordinates: list[Parameter]  # every column's coordinate
    r0: list[np.ndarray]  # per trial, at (friction, effects)
    eq6: list[float]  # per trial, at (friction, effects)
    yaw_fit: list[float]
    columns: dict[str, list[np.ndarray]]  # coordinate name -> per-trial d r / d coordinate
    noise: list[np.ndarray]  # per trial: covariance of its residuals from the input noise (replay_error)
    weights: np.ndarray | None = None  # per trial (trial_weights of the noise, by default)
    bias: list[np.ndarray] | None = None  # per trial: the replay's own miss (replay_error), taken off r0
    # per trial, the residuals of its first START_FIT_S (the rows that fix its start), and their columns
    w0: list[np.ndarray] | None = None
    wcolumns: dict[str, list[np.ndarray]] | None = None
    start_bias: list[np.ndarray] | None = None  # per trial: the replay's own miss on its start rows
    # per trial, the last full replay_errors: its first PAIRED_DRAWS draws (residuals, start rows), its bias and start
    # bias; a paired measurement repeats only those draws and moves that bias by the difference (replay_errors)
    draws: list[tuple] | None = None
    # per trial: the failed joint's scatter taken as noise, its variance per row (diagnose/scatter.py), in its weight
    scatter: list[float] | None = None

    def __post_init__(self):
        if self.weights is None:
            self.weights = trial_weights(self.trials, self.noise, self.scatter)

    def rows(self, names, trials, *, weighted=False) -> tuple:
        """(X, r0, channels, per-trial row counts) over the `trials` indices; `weighted`: each trial's
        rows times its weight."""
        w = [self.weights[k] if weighted else 1.0 for k in trials]
        x = np.vstack(
            [
                w_k * np.column_stack([self.columns[n][k] for n in names]) if names else np.zeros((len(self.r0[k]), 0))
                for k, w_k in zip(trials, w, strict=True)
            ]
        )
        r = np.concatenate([w_k * self.r0[k] for k, w_k in zip(trials, w, strict=True)])
        channels = np.concatenate([residual_channels(self.r0[k]) for k in trials])
        return x, r, channels, [len(self.r0[k]) for k in trials]

    def corrected(self, k: int, residual: np.ndarray) -> np.ndarray:
        """Trial k's residuals of a replay with the replay's bias taken off."""
        return residual if self.bias is None else residual - self.bias[k]

    def start_corrected(self, k: int, residual: np.ndarray) -> np.ndarray:
        """Trial k's start rows with the replay's own miss on them taken off."""
        return residual if self.start_bias is None else residual - self.start_bias[k]

    def eq6_without_miss(self, k: int, corrected: np.ndarray) -> float:
        """Paper Eq. 6 of trial k from its bias-corrected residuals: the final position's error with the
        replay's own miss on this motion (replay_error) taken off, over the distance the head travelled."""
        trial = self.trials[k]
        return simulator_error(
            trial.final_head_xy + FINAL_SIGMA_M * corrected[:2], trial.final_head_xy, trial.initial_head_pose[:2]
        )

    def weighted_rms(self, residuals: list[np.ndarray]) -> float:
        return float(math.sqrt(self.weighted_sum_of_squares(residuals) / sum(len(r) for r in residuals)))

    def weighted_sum_of_squares(self, residuals: list[np.ndarray]) -> float:
        return float(sum(w * w * float(r @ r) for w, r in zip(self.weights, residuals, strict=True)))

    def neg2_log_likelihood(self, residuals: list[np.ndarray], trials=None) -> float:
        """-2 log of the residuals' likelihood (Gaussian, up to a constant), each trial's rows of variance 1 / w^2
        (its weight): the weighted sum of squares plus each trial's rows times log(1 / w^2). Two models whose input
        noise differs, and so their weights, compare on this: a model that calls a trial noisy pays for it.
        `trials`: the indices of the trials to count (all by default)."""
        w, r = self.weights, residuals
        if len(r) != len(w):
            raise ValueError(f"{len(r)} trials' residuals for {len(w)} trials' weights")
        keep = range(len(r)) if trials is None else trials
        return float(sum(w[k] ** 2 * float(r[k] @ r[k]) - 2.0 * len(r[k]) * math.log(w[k]) for k in keep))

    def coordinate(self, name) -> Parameter:
        return next(c for c in self.coordinates if c.name == name)


def trial_weights(trials, noise, scatter=None) -> np.ndarray:
    """Each trial's weight in the fits: 1 / sqrt(1 + v + s) with v its case's mean input-noise variance (in
    standardized units, where the sensor noise is 1) and s its failed joint's scatter per row where one is taken
    (`scatter`, per trial), a scalar feasible generalized least squares. A trial whose replay moves a lot with the
    angle noise alone (a joint-2 failure: final position +-10 cm, measured) tells less about the physics and no
    longer dominates the fit."""
    variance = pooled_per_case(trials, [float(np.mean(np.diag(n))) if len(n) else 0.0 for n in noise])
    extra = scatter or [0.0] * len(trials)
    return np.array([1.0 / math.sqrt(1.0 + variance[t.case] + s) for t, s in zip(trials, extra, strict=True)])


def pooled_per_case(trials, values) -> dict[str, float]:
    """Per case: the mean of its trials' `values` (one trial's few bootstrap replays are too few to trust)."""
    pooled: dict[str, list] = {}
    for trial, value in zip(trials, values, strict=True):
        pooled.setdefault(trial.case, []).append(value)
    return {case: float(np.mean(v)) for case, v in pooled.items()}


def linearize(
    trials,
    friction,
    effects,
    candidates: list[str],
    evaluator: Evaluator,
    *,
    noise=None,
    input_noise_samples=INPUT_NOISE_SAMPLES,
    held=(),
    starts=False,
) -> Linearization:
    """Residuals at (friction, effects) and their forward-difference columns for the friction
    coefficients, the model's own effects and the candidates (and with `starts`, each trial's start:
    start_coordinates); when `noise` is None, the replays' own error (replay_error: their bias, taken off r0,
    and the input noise)."""
    if starts:  # linearized at the trials' own rates, else the protocol's with the IMU's first yaw rate
        trials = [with_start_guess(t) for t in trials]
    coords = (start_coordinates(trials) if starts else []) + friction_coordinates(friction, held)
    for name in list(dict.fromkeys([*(e.name for e in active(effects)), *candidates])):
        coords += effect_coordinates(name, effects)
    base = evaluator.map(evaluate, [(t, friction, effects) for t in trials], "residuals at the model")
    jobs, where = [], []
    for c in coords:
        values = [c2.value + (signed_step(c) if c2 is c else 0.0) for c2 in coords]
        model = model_at(friction, effects, coords, values)
        for k, t in enumerate(trials):
            if c.start_of is not None and c.start_of[0] != k:
                continue  # another trial's start: this trial's replay is base's exactly
            if t.failed_joints or not acts_in_failed_joints_only(c):  # else the replay is base's exactly
                jobs.append((starts_at(trials, coords, values)[k] if c.start_of else t, *model))
                where.append((c.name, k))
    outputs = evaluator.map(evaluate, jobs, f"linearizing at the model ({len(coords)} directions)")
    bias = start_bias = draws = None
    if noise is None:
        bias, noise, start_bias, draws = replay_errors(trials, friction, effects, evaluator, input_noise_samples)
    columns = {c.name: [np.zeros(len(b[0])) for b in base] for c in coords}
    wcolumns = {c.name: [np.zeros(len(b[3])) for b in base] for c in coords}
    for (name, k), o in zip(where, outputs, strict=True):  # residuals have the trial's entries at every model
        step = signed_step(next(c for c in coords if c.name == name))
        columns[name][k] = (o[0] - base[k][0]) / step
        wcolumns[name][k] = (o[3] - base[k][3]) / step
    lin = Linearization(
        trials=list(trials),
        friction=friction,
        effects=dict(effects),
        coordinates=coords,
        r0=[b[0] for b in base],
        eq6=[b[1] for b in base],
        yaw_fit=[b[2] for b in base],
        columns=columns,
        noise=list(noise),
        bias=bias,
        w0=[b[3] for b in base],
        wcolumns=wcolumns,
        start_bias=start_bias,
        draws=draws,
    )
    lin.r0 = [lin.corrected(k, r) for k, r in enumerate(lin.r0)]
    lin.w0 = [lin.start_corrected(k, w) for k, w in enumerate(lin.w0)]
    return lin


def replay_errors(trials, friction, effects, evaluator: Evaluator, samples: int, paired_with=None) -> tuple:
    """Per trial, the replay's bias, its input-noise covariance (replay_error) and the bias of its start rows, at
    (friction, effects), and the first PAIRED_DRAWS draws. `paired_with`: a Linearization whose measurement this
    one is paired with: only the first draws of its last full measurement are replayed (the same noise, on this
    model's twins), and that measurement's bias and start bias moved by their mean difference; its covariance kept.
    The paired difference is precise where a full measurement's mean is not (common random numbers)."""
    count = min(samples, PAIRED_DRAWS) if paired_with is not None else samples
    # Twins first, then every draw a job of its own: a campaign of a few trials keeps every core busy.
    twins = evaluator.map(
        bootstrap_twin, [(t, friction, effects) for t in trials], "the replays' own error: noise-free twins"
    )
    jobs = [(*made, friction, effects, k, i) for k, made in enumerate(twins) for i in range(count)]
    what = "the replays' own error: the twins replayed with noisy angles" + (" (paired)" if paired_with else "")
    out = iter(evaluator.map(bootstrap_draw, jobs, what))
    drawn = [[next(out) for _ in range(count)] for _ in twins]
    firsts = [tuple(np.array([d[part] for d in ds[:PAIRED_DRAWS]]) for part in (0, 1)) for ds in drawn]
    if paired_with is not None:
        moved_by = [
            (b + (r - ref_r[: len(r)]).mean(axis=0), s + (w - ref_w[: len(w)]).mean(axis=0))
            for (r, w), (ref_r, ref_w, b, s) in zip(firsts, paired_with.draws, strict=True)
        ]
        return [m[0] for m in moved_by], paired_with.noise, [m[1] for m in moved_by], paired_with.draws
    errors = [draws_mean_and_covariance(ds) for ds in drawn]
    # The bias is a mean of `samples` draws: taking it off adds 1 / samples of their covariance.
    bias, start = [e[0] for e in errors], [e[2] for e in errors]
    draws = [(*first, b, s) for first, b, s in zip(firsts, bias, start, strict=True)]
    return bias, [e[1] * (1.0 + 1.0 / samples) for e in errors], start, draws


def with_replay_error(lin: Linearization, evaluator: Evaluator, samples: int, paired: bool = False) -> Linearization:
    """`lin` with the replay's bias and input noise measured again at its model (their residuals moved
    from the old bias to the new one, the trial weights recomputed); `paired`: by the paired draws (replay_errors)."""
    new = _measured_error(lin, lin.trials, lin.friction, lin.effects, evaluator, samples, paired)
    old_bias, old_start = lin.bias or [None] * len(lin.r0), lin.start_bias or [None] * len(lin.w0)
    r0 = [r + _moved_bias(before, after) for r, before, after in zip(lin.r0, old_bias, new.bias, strict=True)]
    w0 = [w + _moved_bias(b, a) for w, b, a in zip(lin.w0, old_start, new.start_bias, strict=True)]
    return dataclasses.replace(new, r0=r0, w0=w0)


def _measured_error(lin: Linearization, trials, friction, effects, evaluator, samples: int, paired: bool):
    """`lin` with the replay's own error at (friction, effects) on `trials` (replay_errors, paired with lin's last
    full measurement where `paired` and it has one): its bias, input noise, trial weights, start bias and draws."""
    bias, noise, start_bias, draws = replay_errors(
        trials, friction, effects, evaluator, samples, lin if paired and lin.draws else None
    )
    return dataclasses.replace(
        lin,
        bias=bias,
        noise=noise,
        weights=trial_weights(lin.trials, noise, lin.scatter),
        start_bias=start_bias,
        draws=draws,
    )


def _moved_bias(before, after):
    """What moves a residual from one replay bias taken off to another (None: none taken off)."""
    return (0.0 if before is None else before) - after


def moved(lin: Linearization, names: list[str], values, evaluator, **kwargs) -> Linearization:
    """`lin` relinearized (relinearize) where the coordinates `names` take `values` (starts included)."""
    coords = [lin.coordinate(n) for n in names]
    return relinearize(
        lin,
        *model_at(lin.friction, lin.effects, coords, values),
        evaluator,
        trials=starts_at(lin.trials, coords, values),
        **kwargs,
    )


def relinearize(
    lin: Linearization,
    friction,
    effects,
    evaluator,
    what="residuals at the new model",
    samples=0,
    trials=None,
    paired=False,
) -> Linearization:
    """The residuals at the new model; the columns updated by Broyden's rank-one secant update along the
    step (no replays: the columns of the coordinates that moved become secants through both points, so
    a nonlinear response is followed); the replay's bias and input noise reused, or with `samples`
    measured again at the new model (replay_error; `paired`: by the paired draws) before the update, so that the
    secants follow the residuals with the replay's own miss taken off. `trials`: the trials with their starts at the
    new model."""
    trials = list(trials or lin.trials)
    out = evaluator.map(evaluate, [(t, friction, effects) for t in trials], what)
    target = lin
    if samples:
        target = _measured_error(lin, trials, friction, effects, evaluator, samples, paired)
    values = coordinate_values(lin.coordinates, friction, effects, trials)
    step = np.array(values) - np.array([c.value for c in lin.coordinates])
    names = [c.name for c in lin.coordinates]
    columns = {n: list(cols) for n, cols in lin.columns.items()}
    wcolumns = {n: list(cols) for n, cols in lin.wcolumns.items()}
    r0 = [target.corrected(k, o[0]) for k, o in enumerate(out)]
    w0 = [target.start_corrected(k, o[3]) for k, o in enumerate(out)]
    if step @ step > 0:  # residuals have the trial's entries at every model: the secants line up
        for k in range(len(out)):
            for cols, old, now in ((columns, lin.r0[k], r0[k]), (wcolumns, lin.w0[k], w0[k])):
                jacobian = np.column_stack([cols[n][k] for n in names])
                jacobian += np.outer(now - old - jacobian @ step, step) / (step @ step)
                for j, n in enumerate(names):
                    cols[n][k] = jacobian[:, j]
    coords = [dataclasses.replace(c, value=v) for c, v in zip(lin.coordinates, values, strict=True)]
    return dataclasses.replace(
        target,
        trials=trials,
        friction=friction,
        effects=dict(effects),
        coordinates=coords,
        r0=r0,
        columns=columns,
        eq6=[o[1] for o in out],
        yaw_fit=[o[2] for o in out],
        w0=w0,
        wcolumns=wcolumns,
    )


def visibility(lin: Linearization, name: str) -> dict[str, dict[str, float]]:
    """Per case: how much the final position (cm) and the path or yaw-rate channel (standardized RMS)
    change per probe step of each of the candidate's coordinates, averaged over the case's trials."""
    out: dict[str, dict[str, float]] = {}
    for c in [c for c in lin.coordinates if c.owner == name]:
        for case in dict.fromkeys(t.case for t in lin.trials):
            ks = [k for k, t in enumerate(lin.trials) if t.case == case]
            cols = [lin.columns[c.name][k] * c.step for k in ks]
            row = out.setdefault(case, {})
            row[f"{c.name}: final position cm per {c.step:g}"] = float(
                np.mean([100 * FINAL_SIGMA_M * np.linalg.norm(col[:2]) for col in cols])
            )
            row[f"{c.name}: path rms (standardized) per {c.step:g}"] = float(
                np.mean([np.sqrt(np.mean(col[2:] ** 2)) if len(col) > 2 else 0.0 for col in cols])
            )
    return out
