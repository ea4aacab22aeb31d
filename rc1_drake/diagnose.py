"""Find the missing physics (issue 6): fit today's model, see where it fails, rank the candidate effects
(effects.py) on held-out trials, accept one only when it is significant and holds on trials it was not
fitted to, add it, and repeat until nothing more is found; the waterfall shows what each step bought.

The method, linearized where that is safe and checked by simulation where it decides:

1. Linearize. At the current model, the stacked standardized residuals r0 of every trial's replay
   (sysid.residual.trial_residual: final position, camera path or yaw rate) and their Jacobian by forward
   differences: one column per friction coefficient, one per candidate coordinate at its probe step
   (a small, clearly visible strength: EffectParameter.probe). What the replay itself gets wrong is
   taken once, by a parametric bootstrap on each trial's noise-free twin (replay_error): its mean is
   subtracted from every residual of that trial (the replay's bias), its covariance is the input noise.
2. Fit. For today's model (the friction coefficients these data identify, identify.screen's rule) and
   for it plus each candidate: the bounded least squares of r0 + J d (a Drake MathematicalProgram), the
   parameters' sandwich covariance with the input noise, their Wald test against 0 (the nested value),
   the leave-one-trial-out held-out error of the linear model, and AIC.
3. Decide. The candidate with the largest held-out reduction among the significant ones is checked by
   simulation: every trial replayed with the parameters fitted without it, for today's model and for the
   candidate. It is accepted only when it is significant (Wald p below P_ACCEPT) and the simulated
   held-out error falls by ACCEPT_HELD_OUT_REDUCTION (half) at least; one that lowers it by less (but by
   MIN_HELD_OUT_REDUCTION at least) explains part of it, and is reported, not accepted. Candidates whose
   columns, after the friction's are projected out, are nearly parallel (cosine above
   INDISTINGUISHABLE_COS) cannot be told apart by these data; an effect whose largest physical value
   would not be significant here is "not detectable here", and the probe study (probe_visibility) names
   the kind of trial that would see it.
4. Repeat at the new model while what is left is not consistent with the noise: its residuals are
   simulated again, the Jacobian's columns updated by Broyden's secant update along the step (no new
   replays), the replay's own error measured again there (it depends on the model), the accepted model
   estimated further by Gauss-Newton steps (_polish: the decision was taken at a bounded fit), today's parameters
   (friction, accepted effects) refitted and moved where simulation confirms it, and the remaining
   candidates ranked there.

The verdict: `effect_found` when effects were accepted and what is left is consistent with the noise (the
final positions' chi-squared with the hand and input noise, the replay's bias taken off);
`no_missing_effect` when nothing was accepted and the misfit is consistent with the noise; `ambiguous`
when two candidates explain the held-out trials alike (the runner-up's simulated held-out sum of squares
within AMBIGUOUS_RATIO of the best's), with the kind of trial that would tell them apart; `unexplained`
when a misfit remains that no candidate explains, or that a candidate explains only in part (any accepted
effects, and a candidate that helped by less than half, are then reported as partial).
"""

import dataclasses
import math
import os
import time
from typing import Callable, Dict, List, Optional

import numpy as np

from .config import FRICTION_NAMES, RESIDUAL_SIGMAS, START_MODES, Z95, Friction
from .effects import LIBRARY, active, candidate_names, effect_values, potentiometer_faults
from .engine import default_engine
from .replay import with_start_guess
from .start import START_FIT_S, START_NAMES, start_residual
from .sysid.evaluate import replay, replayer
from .sysid.optimize import bounded_step
from .sysid.parameters import DEFAULT_PARAMETERS, difference_step
from .sysid.residual import residual_channels, trial_residual
from .sysid.stats import channel_variances

P_ACCEPT = 2.7e-3  # Wald test of a candidate's parameters against 0: |z| > 3 for one parameter
MIN_HELD_OUT_REDUCTION = 0.10  # a candidate "helps" when the simulated held-out error falls by this fraction
# An accepted effect must at least halve the simulated held-out error; one that helps by less explains part
# of it and is reported, not accepted. Measured on 3 x 2 s campaigns (benchmarks/diagnosis.py): the true
# effects accepted removed 53-81% (toe 72-81%, head drag 53-71%; the shipped campaign's toe 97%), and 6 of
# the 8 wrong effects accepted in a true one's place removed 17-49%.
ACCEPT_HELD_OUT_REDUCTION = 0.5
# A rival whose simulated held-out sum of squares is below this multiple of the best one's explains the data
# alike: no decision. Measured on 3 x 2 s campaigns (benchmarks/diagnosis.py): a true toe or lateral asymmetry
# left 1.7-2x less than its best rival; a joint Coulomb friction or head drag was "explained" by a wrong effect
# leaving 1.04-1.08x less than another wrong one.
AMBIGUOUS_RATIO = 1.5
INDISTINGUISHABLE_COS = 0.95
P_MISFIT = 1e-3  # the final positions' misfit is "consistent with the noise" above this p-value
MAX_ROUNDS = 3
REFINED_CANDIDATES = 3  # the best candidates by the linear ranking, refined by a secant step before the checks
TRUST_STEPS = 4.0  # an effect coordinate's linear fit moves at most this many probe steps per round
POLISH_STEPS = 3  # Gauss-Newton steps on an accepted model, while simulation confirms them (_polish)
POLISH_TOLERANCE = 0.5  # ... and while the accepted effect's step exceeds this many standard errors
INPUT_NOISE_SAMPLES = 6  # bootstrap replays per trial for the replay's bias and input noise (replay_error)
# A trial's start (its head's vx, vy, yaw rate at t = 0) as nuisance coordinates: forward-difference steps
# and bounds (m/s, m/s, rad/s). Its first START_FIT_S of data, not a convention, fix it in every fit (fit).
START = "start"
START_STEPS = (0.02, 0.02, 0.1)
START_BOUNDS = (1.0, 1.0, 5.0)
FINAL_SIGMA_M = RESIDUAL_SIGMAS["final_m"]


@dataclasses.dataclass
class Coordinate:
    """A direction of the linearization: a friction coefficient or one coordinate of an effect."""

    name: str
    owner: str  # "friction", START or the effect's name
    value: float
    lower: float
    upper: float
    step: float
    start_of: Optional[tuple] = None  # a START coordinate's (trial index, index in START_NAMES)


def friction_coordinates(friction: Friction, held=()) -> List[Coordinate]:
    out = []
    for p in [p for p in DEFAULT_PARAMETERS if p.name not in held]:
        value = getattr(friction, p.name)
        out.append(Coordinate(p.name, "friction", value, p.lower, p.upper, difference_step(p, value)))
    return out


def effect_coordinates(name: str, effects: Dict[str, float]) -> List[Coordinate]:
    effect = LIBRARY[name]
    values = effect.coordinates(effect_values(effects, effect))
    return [Coordinate(p.key, name, float(values[p.key]), min(p.lower, values[p.key]), max(p.upper, values[p.key]),
                       p.probe_step) for p in effect.coordinate_space()]


def start_coordinates(trials) -> List[Coordinate]:
    """Each trial's head rates at t = 0 (Trial.initial_head_rates, which must be set) as three coordinates."""
    return [Coordinate(f"{t.trial_id}:{name}", START, float(t.initial_head_rates[i]), -bound, bound, step, (k, i))
            for k, t in enumerate(trials)
            for i, (name, step, bound) in enumerate(zip(START_NAMES, START_STEPS, START_BOUNDS, strict=True))]


def starts_at(trials, coordinates: List[Coordinate], values) -> list:
    """`trials` with their START coordinates among `coordinates` set to `values`."""
    out = list(trials)
    for c, v in zip(coordinates, values, strict=True):
        if c.owner == START:
            k, i = c.start_of
            rates = out[k].initial_head_rates.copy()
            rates[i] = float(v)
            out[k] = dataclasses.replace(out[k], initial_head_rates=rates)
    return out


def physics_names(lin, names) -> List[str]:
    """`names` without the trials' start coordinates: the model's parameters (what the misfit's dof count)."""
    return [n for n in names if lin.coordinate(n).owner != START]


def model_at(friction: Friction, effects: Dict[str, float], coordinates: List[Coordinate], values) -> tuple:
    """(friction, effects) with the coordinates set to `values` (effects written back through their classes;
    START coordinates belong to the trials: starts_at)."""
    friction = dataclasses.replace(friction, **{c.name: float(v) for c, v in zip(coordinates, values, strict=True)
                                                if c.owner == "friction"})
    effects = dict(effects)
    for owner in dict.fromkeys(c.owner for c in coordinates if c.owner not in ("friction", START)):
        effect = LIBRARY[owner]
        current = effect.coordinates(effect_values(effects, effect))
        current.update({c.name: float(v) for c, v in zip(coordinates, values, strict=True) if c.owner == owner})
        effects.update(effect.from_coordinates(current))
    return friction, effects


# ---------------------------------------------------------------------------------------------- simulation

def _evaluate(trial, friction, effects) -> tuple:
    """One replay, scored: (standardized residuals, Eq. 6 error %, yaw-rate fit %, its end time s, the
    standardized residuals of its first START_FIT_S at the full sampling rate: start.start_residual)."""
    from .compare import fit_percent, simulator_error

    run = replay(trial, friction, effects)
    t = trial.t - trial.t[0]
    inside = t <= run.t[-1] + 1e-9
    fit = fit_percent(trial.head_yaw_rate[inside], np.interp(t[inside], run.t, run.head_yaw_rate))
    return (trial_residual(trial, run), simulator_error(run.head_xy[-1], trial.final_head_xy,
                                                            trial.initial_head_pose[:2]), fit, float(run.t[-1]),
            start_residual(trial, run, START_FIT_S))


def replay_error(trial, friction, effects, until: float, samples: int, seed: int) -> tuple:
    """What replaying this trial gets wrong, by a parametric bootstrap on its noise-free twin
    (synthesize.noise_free_twin, made by the model): `samples` draws of the trial's potentiometer noise
    (as its smoothing estimates it: Replayer.angle_noise_rad) on the twin's angles, each replayed at the model and
    scored against the twin up to `until` (the trial's own replay's end), so that the draws line up
    with the trial's residuals. Returns (bias, covariance): the draws' mean residual — the replay's own
    miss on this motion, from its start state, its smoothing of noisy angles and its stiff servos
    (measured on 3 s no-failure trials: the noise alone shifts the start transient by what a 0.3 deg
    toe would, trial after trial) — and their covariance (the input noise; a joint-2 failure, which
    circles, replays chaotically: there it is large). None when the draws do not line up.
    (In this process; _replay_errors spreads the twins and the draws over an executor, with the same result.)"""
    made = bootstrap_twin(trial, friction, effects, until)
    if made is None:
        return None
    return _draws_mean_and_covariance([bootstrap_draw(*made, friction, effects, until, seed, i)
                                       for i in range(samples)])[:2]


def bootstrap_twin(trial, friction, effects, until: float) -> Optional[tuple]:
    """replay_error's twin, with the trial's camera misses and its final position at `until` (so that the
    samples kept are the trial's), and the trial's angle noise (rad); None when the twin's samples do not
    line up with the trial's."""
    from .synthesize import noise_free_twin

    twin = noise_free_twin(trial, friction=friction, effects=effects, head_at=until)
    if trial.initial_head_rates is None:  # replayed from the convention, as the trial is
        twin = dataclasses.replace(twin, initial_head_rates=None)
    if len(twin.t) != len(trial.t):
        return None
    camera = None
    if trial.camera is not None:
        camera = twin.camera.copy()
        camera[np.isnan(trial.camera[:, 0])] = np.nan
    return dataclasses.replace(twin, camera=camera), replayer(trial).angle_noise_rad()


_TWIN_REPLAYERS: dict = {}  # per worker process: a twin (its id and angles) -> its Replayer, the last few only


def bootstrap_draw(twin, sigma_rad: float, friction, effects, until: float, seed: int, index: int) -> tuple:
    """Draw `index` of replay_error: the twin replayed at the model from its angles plus the `index`-th noise
    draw of the stream `seed` (so that draws split over processes are the ones one process would make); its
    residuals, and those of its start rows (start.start_residual)."""
    from .replay import Replayer

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
    return trial_residual(twin, run, until=until), start_residual(twin, run, START_FIT_S)


def _draws_mean_and_covariance(draws) -> Optional[tuple]:
    """(mean, covariance) of the draws' residuals, and the mean of their start rows' (None where they differ)."""
    if len({len(d[0]) for d in draws}) != 1:
        return None
    residuals = np.array([d[0] for d in draws])
    deviation = residuals - residuals.mean(axis=0)
    start = np.mean([d[1] for d in draws], axis=0) if len({len(d[1]) for d in draws}) == 1 else None
    return residuals.mean(axis=0), deviation.T @ deviation / max(len(draws) - 1, 1), start


def _replay_and_score(trial, friction, effects) -> tuple:
    from .compare import score_trial

    run = replay(trial, friction, effects)
    return score_trial(trial, run), run


class Evaluator:
    """Runs batches of (trial, friction, effects) replays on an executor, counting them."""

    def __init__(self, executor, progress: Optional[Callable[[str], None]] = None):
        self.executor, self.progress, self.simulations = executor, progress, 0

    def map(self, function, jobs, what: str) -> list:
        if self.progress:
            self.progress(f"{what}: {len(jobs)} replays")
        self.simulations += len(jobs)
        if self.executor is None:
            return [function(*job) for job in jobs]
        return [f.result() for f in [self.executor.submit(function, *job) for job in jobs]]


# --------------------------------------------------------------------------------------------- linear algebra

@dataclasses.dataclass
class Linearization:
    trials: list
    friction: Friction
    effects: Dict[str, float]
    coordinates: List[Coordinate]  # every column's coordinate
    r0: List[np.ndarray]  # per trial, at (friction, effects)
    eq6: List[float]  # per trial, at (friction, effects)
    yaw_fit: List[float]
    columns: Dict[str, List[np.ndarray]]  # coordinate name -> per-trial d r / d coordinate
    noise: List[np.ndarray]  # per trial: covariance of its residuals from the input noise (replay_error)
    weights: Optional[np.ndarray] = None  # per trial (trial_weights of the noise, by default)
    bias: Optional[List[np.ndarray]] = None  # per trial: the replay's own miss (replay_error), taken off r0
    ends: Optional[List[float]] = None  # per trial: where its replay at (friction, effects) ended, s
    # per trial, the residuals of its first START_FIT_S (the rows that fix its start), and their columns
    w0: Optional[List[np.ndarray]] = None
    wcolumns: Optional[Dict[str, List[np.ndarray]]] = None
    start_bias: Optional[List[np.ndarray]] = None  # per trial: the replay's own miss on its start rows

    def __post_init__(self):
        if self.weights is None:
            self.weights = trial_weights(self.trials, self.noise)

    def rows(self, names, trials, *, weighted=False) -> tuple:
        """(X, r0, channels, per-trial row counts) over the `trials` indices; `weighted`: each trial's
        rows times its weight."""
        w = [self.weights[k] if weighted else 1.0 for k in trials]
        x = np.vstack([w_k * np.column_stack([self.columns[n][k] for n in names]) if names else
                       np.zeros((len(self.r0[k]), 0)) for k, w_k in zip(trials, w, strict=True)])
        r = np.concatenate([w_k * self.r0[k] for k, w_k in zip(trials, w, strict=True)])
        channels = np.concatenate([residual_channels(self.r0[k]) for k in trials])
        return x, r, channels, [len(self.r0[k]) for k in trials]

    def corrected(self, k: int, residual: np.ndarray) -> np.ndarray:
        """Trial k's residuals of a replay with the replay's bias taken off (only the final position's when
        this replay stops elsewhere than the one the bias was taken on)."""
        bias = None if self.bias is None else self.bias[k]
        if bias is None:
            return residual
        if len(residual) == len(bias):
            return residual - bias
        out = residual.copy()
        out[:2] -= bias[:2]
        return out

    def start_corrected(self, k: int, residual: np.ndarray) -> np.ndarray:
        """Trial k's start rows with the replay's own miss on them taken off (where it lines up)."""
        bias = None if self.start_bias is None else self.start_bias[k]
        return residual if bias is None or len(bias) != len(residual) else residual - bias

    def eq6_without_miss(self, k: int, corrected: np.ndarray) -> float:
        """Paper Eq. 6 of trial k from its bias-corrected residuals: the final position's error with the
        replay's own miss on this motion (replay_error) taken off, over the distance the head travelled."""
        from .compare import simulator_error

        trial = self.trials[k]
        return simulator_error(trial.final_head_xy + FINAL_SIGMA_M * corrected[:2], trial.final_head_xy,
                               trial.initial_head_pose[:2])

    def weighted_rms(self, residuals: List[np.ndarray]) -> float:
        return float(math.sqrt(self.weighted_sum_of_squares(residuals) / sum(len(r) for r in residuals)))

    def weighted_sum_of_squares(self, residuals: List[np.ndarray]) -> float:
        return float(sum(w * w * float(r @ r) for w, r in zip(self.weights, residuals, strict=True)))

    def coordinate(self, name) -> Coordinate:
        return next(c for c in self.coordinates if c.name == name)


def bounded_least_squares(x, r, lower, upper) -> np.ndarray:
    """argmin |r + x d|^2 subject to lower <= d <= upper, as a Drake MathematicalProgram (columns scaled
    to unit norm; a column that never changes the residuals stays at 0)."""
    d = np.zeros(x.shape[1])
    norm = np.linalg.norm(x, axis=0)
    seen = norm > 1e-12
    if not seen.any():
        return d
    scaled = x[:, seen] / norm[seen]
    d[seen] = bounded_step(scaled, r, 1e-10, lower[seen] * norm[seen], upper[seen] * norm[seen]) / norm[seen]
    return d


@dataclasses.dataclass
class Fit:
    names: List[str]
    values: np.ndarray  # coordinate values at the fit
    steps: np.ndarray  # d from the linearization point
    standard_errors: np.ndarray
    covariance: np.ndarray
    residual: List[np.ndarray]  # per trial, r0 + X d (linear prediction, all trials)
    held_out: List[np.ndarray]  # per trial, the prediction from the fit without that trial
    held_out_steps: List[np.ndarray]  # per trial, d fitted without it
    aic: float

    def held_out_sum_of_squares(self) -> float:
        return float(sum(float(h @ h) for h in self.held_out))


def _own_start(coords, k: int) -> List[int]:
    """The indices among `coords` of trial k's own START coordinates."""
    return [i for i, c in enumerate(coords) if c.start_of is not None and c.start_of[0] == k]


def _start_rows(lin: Linearization, coords, k: int) -> tuple:
    """Trial k's start rows (Linearization.w0) and their columns by `coords`."""
    w = lin.w0[k]
    return w, np.column_stack([lin.wcolumns[c.name][k] for c in coords]) if coords else np.zeros((len(w), 0))


def _profiled_rows(lin: Linearization, coords, trials) -> tuple:
    """lin.rows (weighted) over the physics among `coords`, each trial's start profiled out: where its start
    s = -G (w + W p) is fitted to its start rows (w, W; G = pinv(W_s)) for any physics step p, its rows
    r + X p + A s are r - A G w + (X - A G W) p (A: its start columns). Also, per trial, A G (weighted; None
    without a start of its own), which carries the start rows' noise into its rows."""
    physics = [c for c in coords if c.start_of is None]
    x, r, channels, counts = lin.rows([c.name for c in physics], trials, weighted=True)
    carries, start = [], 0
    for k, n in zip(trials, counts, strict=True):
        own = [coords[i] for i in _own_start(coords, k)]
        carry = None
        if own:
            w, big_w = _start_rows(lin, own + physics, k)
            carry = lin.weights[k] * np.column_stack([lin.columns[c.name][k] for c in own]) @ np.linalg.pinv(
                big_w[:, :len(own)])
            r[start:start + n] -= carry @ w
            x[start:start + n] -= carry @ big_w[:, len(own):]
        carries.append(carry)
        start += n
    return x, r, channels, counts, carries


def _solve(lin: Linearization, coords, trials, lower, upper) -> np.ndarray:
    """The bounded least-squares step of `coords` on `trials`: the physics on all rows, each trial's start on
    its start rows given the physics (_profiled_rows)."""
    d = np.zeros(len(coords))
    physics = [i for i, c in enumerate(coords) if c.start_of is None]
    x, r, _, _, _ = _profiled_rows(lin, coords, trials)
    d[physics] = bounded_least_squares(x, r, lower[physics], upper[physics])
    for k in trials:
        _fit_own_start(lin, coords, k, d, lower, upper)
    return d


def _fit_own_start(lin: Linearization, coords, k: int, d, lower, upper) -> None:
    """Set d's entries of trial k's start to their fit on its start rows, the other entries held."""
    idx = _own_start(coords, k)
    if idx:
        w, big_w = _start_rows(lin, coords, k)
        others = [i for i in range(len(coords)) if i not in idx]
        target = w + big_w[:, others] @ d[others]
        d[idx] = np.clip(-np.linalg.pinv(big_w[:, idx]) @ target, lower[idx], upper[idx])


def _start_rows_variance(lin: Linearization, coords, k: int, d) -> float:
    """The variance of trial k's start rows about the fit d (standardized units; their own dof)."""
    w, big_w = _start_rows(lin, coords, k)
    e = w + big_w @ d
    return float(e @ e) / max(len(e) - len(_own_start(coords, k)), 1)


def fit(lin: Linearization, names: List[str]) -> Fit:
    """Bounded weighted linear least squares over `names` (each trial's rows times its weight; a trial's
    start, where among them, fitted to its first START_FIT_S only: _solve), its covariance (the sandwich
    with channel variances and input noise, or the trial jackknife where that is larger), and
    leave-one-trial-out predictions."""
    coords = [lin.coordinate(n) for n in names]
    reach = np.array([math.inf if c.owner == "friction" else TRUST_STEPS * c.step for c in coords])
    lower = np.maximum(np.array([c.lower - c.value for c in coords]), -reach)
    upper = np.minimum(np.array([c.upper - c.value for c in coords]), reach)
    everything = list(range(len(lin.trials)))
    x_all, r_all, channels, counts = lin.rows(names, everything, weighted=True)
    d = _solve(lin, coords, everything, lower, upper)
    e = r_all + x_all @ d
    variance = channel_variances(e, channels, len(names))
    physics = [i for i, c in enumerate(coords) if c.start_of is None]
    x, _, _, _, carries = _profiled_rows(lin, coords, everything)
    inv = np.linalg.pinv(x.T @ x) if physics else np.zeros((0, 0))
    middle = np.zeros_like(inv)
    start_variances, start = {}, 0
    for k, (n, carry) in enumerate(zip(counts, carries, strict=True)):
        sigma = np.diag(variance[start:start + n]) + lin.weights[k] ** 2 * lin.noise[k]
        if carry is not None:
            start_variances[k] = _start_rows_variance(lin, coords, k, d)
            sigma = sigma + start_variances[k] * carry @ carry.T
        middle += x[start:start + n].T @ sigma @ x[start:start + n]
        start += n
    cov = np.zeros((len(names), len(names)))
    cov[np.ix_(physics, physics)] = inv @ middle @ inv
    for k, v in start_variances.items():  # a start's: its start rows' noise and what the physics' uncertainty moves
        idx = _own_start(coords, k)
        _, big_w = _start_rows(lin, coords, k)
        g = np.linalg.pinv(big_w[:, idx])
        through = g @ big_w[:, physics]
        cov[np.ix_(idx, idx)] = v * g @ g.T + through @ cov[np.ix_(physics, physics)] @ through.T
    per_trial = [part / w for part, w in zip(np.split(e, np.cumsum(counts)[:-1]), lin.weights, strict=True)]
    held, held_steps = [], []
    for k in everything:
        rest = [j for j in everything if j != k]
        if not rest:
            held.append(lin.r0[k].copy())
            held_steps.append(np.zeros(len(names)))
            continue
        dk = _solve(lin, coords, rest, lower, upper)
        _fit_own_start(lin, coords, k, dk, lower, upper)  # its start is its own: fitted to it, physics held
        held.append(lin.r0[k] + lin.rows(names, [k])[0] @ dk)
        held_steps.append(dk)
    if len(everything) >= 3 and physics:  # a trial's start is its own: no jackknife
        # The trial jackknife sees what the sandwich assumes away: residuals correlated within a trial, and
        # a replay that misses its trial by more than the noise (measured: the toe fitted per trial of the
        # shipped campaign scatters 1.9-2.7 deg, where the sandwich's standard error was 0.04).
        steps = np.array(held_steps)[:, physics]
        jackknife = (len(steps) - 1) / len(steps) * (steps - steps.mean(axis=0)).T @ (steps - steps.mean(axis=0))
        block = np.ix_(physics, physics)
        if np.trace(jackknife) > np.trace(cov[block]):
            cov[block] = jackknife
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    m = len(e)
    aic = m * math.log(max(float(e @ e), 1e-300) / m) + 2 * len(names)
    return Fit(names=list(names), values=np.array([c.value for c in coords]) + d, steps=d, standard_errors=se,
               covariance=cov, residual=per_trial, held_out=held, held_out_steps=held_steps, aic=aic)


def trial_weights(trials, noise) -> np.ndarray:
    """Each trial's weight in the fits: 1 / sqrt(1 + v) with v its case's mean input-noise variance (in
    standardized units, where the sensor noise is 1), a scalar feasible generalized least squares. A trial
    whose replay moves a lot with the angle noise alone (a joint-2 failure: final position +-10 cm, measured)
    tells less about the physics and no longer dominates the fit."""
    variance = _pooled_per_case(trials, [float(np.mean(np.diag(n))) if len(n) else 0.0 for n in noise])
    return np.array([1.0 / math.sqrt(1.0 + variance[t.case]) for t in trials])


def _pooled_per_case(trials, values) -> Dict[str, float]:
    """Per case: the mean of its trials' `values` (one trial's few bootstrap replays are too few to trust)."""
    pooled: Dict[str, list] = {}
    for trial, value in zip(trials, values, strict=True):
        pooled.setdefault(trial.case, []).append(value)
    return {case: float(np.mean(v)) for case, v in pooled.items()}


def interval95(value: float, standard_error: float) -> List[float]:
    return [value - Z95 * standard_error, value + Z95 * standard_error]


def wald_p(fitted: Fit, names: List[str]) -> float:
    """p-value of the Wald test that the coordinates `names` are 0 (chi-squared, one dof per coordinate)."""
    from scipy.stats import chi2

    idx = [fitted.names.index(n) for n in names]
    value = fitted.values[idx]
    cov = fitted.covariance[np.ix_(idx, idx)]
    stat = float(value @ np.linalg.pinv(cov) @ value) if np.any(np.diag(cov) > 0) else 0.0
    return float(chi2.sf(stat, len(idx)))


def _final_position_variances(lin: Linearization) -> Dict[str, float]:
    """Per case: the final position's variance per axis, standardized (hand noise 1 plus the input noise,
    pooled per case: one trial's few bootstrap replays estimate a variance too loosely)."""
    pooled = _pooled_per_case(lin.trials, [float(np.mean(np.diag(noise)[:2])) for noise in lin.noise])
    return {case: 1.0 + v for case, v in pooled.items()}


def final_misfit(lin: Linearization, residual: List[np.ndarray], free: int, exclude=()) -> tuple:
    """(chi-squared, dof, p) of the final positions of the trials not in `exclude` (ids) against the hand
    noise (RESIDUAL_SIGMAS, 1 in standardized units) plus the input noise."""
    from scipy.stats import chi2

    variance = _final_position_variances(lin)
    kept = [(t, r) for t, r in zip(lin.trials, residual, strict=True) if t.trial_id not in exclude]
    stat = float(sum(float(r[:2] @ r[:2]) / variance[t.case] for t, r in kept))
    dof = max(2 * len(kept) - free, 1)
    return stat, dof, float(chi2.sf(stat, dof))


@dataclasses.dataclass
class Misfit:
    """What a model leaves in the final positions: the campaign's p-value without the outlying trials,
    and those trials (each far beyond the noise on its own: p below P_MISFIT / trials)."""

    p: float
    outliers: Dict[str, dict]  # trial -> {"off_cm", "noise_cm", "p"}

    @property
    def consistent(self) -> bool:
        return self.p > P_MISFIT


MAX_OUTLIER_FRACTION = 0.1  # more outlying trials than this: the misfit is the campaign's, not theirs


def misfit(lin: Linearization, residual: List[np.ndarray], free: int) -> Misfit:
    from scipy.stats import chi2

    variance = _final_position_variances(lin)
    outliers = {}
    for t, r in zip(lin.trials, residual, strict=True):
        p = float(chi2.sf(float(r[:2] @ r[:2]) / variance[t.case], 2))
        if p < P_MISFIT / len(lin.trials):
            outliers[t.trial_id] = {"off_cm": 100 * FINAL_SIGMA_M * float(np.linalg.norm(r[:2])),
                                    "noise_cm": 100 * FINAL_SIGMA_M * math.sqrt(variance[t.case]), "p": p}
    if len(outliers) > MAX_OUTLIER_FRACTION * len(lin.trials):
        return Misfit(p=final_misfit(lin, residual, free)[2], outliers=outliers)
    return Misfit(p=final_misfit(lin, residual, free, exclude=outliers)[2], outliers=outliers)


def _orthogonal_to(x, basis) -> np.ndarray:
    if basis.shape[1] == 0:
        return x
    q, _ = np.linalg.qr(basis)
    return x - q @ (q.T @ x)


def subspace_cosine(a, b) -> float:
    """Cosine of the smallest angle between the column spaces of a and b."""
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False).max())


# ------------------------------------------------------------------------------------------------ reports

@dataclasses.dataclass
class CandidateResult:
    name: str
    parameters: Dict[str, float]  # the effect's parameters at the fit
    coordinates: Dict[str, List[float]]  # coordinate -> [value, standard error]
    interval95: Dict[str, List[float]]
    wald_p: float
    held_out_before: float  # RMS of the standardized held-out residuals, today's model (linear prediction)
    held_out_after: float
    held_out_reduction: float  # 1 - (after / before)^2: the fraction of the held-out sum of squares removed
    aic_delta: float
    score: float  # the held-out reduction: the ranking
    status: str  # accepted | not significant | no held-out gain | not detectable here | ...
    accepted: bool = False
    detectable_strength: Dict[str, float] = dataclasses.field(default_factory=dict)  # 3 standard errors
    indistinguishable_from: List[str] = dataclasses.field(default_factory=list)
    visibility: Dict[str, Dict[str, float]] = dataclasses.field(default_factory=dict)  # case -> channel -> per unit
    simulated: Optional[dict] = None  # the check by simulation, when it was made
    experiment: Optional[str] = None  # the kind of trial that would see it / tell it apart


@dataclasses.dataclass
class HeldOutScore:
    """Per-trial scores of a model (a replay per trial, each with the parameters fitted without it)."""

    label: str
    effects: Dict[str, float]
    sum_of_squares: float
    eq6_pct: Dict[str, float]  # trial -> Eq. 6 error
    yaw_fit_pct: Dict[str, float]
    eq6_without_miss_pct: Dict[str, float]  # trial -> Eq. 6 error with the replay's own miss taken off

    def by_case(self, trials) -> Dict[str, dict]:
        ids = [t.trial_id for t in trials]
        return _cases(trials, [self.eq6_pct[i] for i in ids], [self.yaw_fit_pct[i] for i in ids],
                      [self.eq6_without_miss_pct[i] for i in ids])

    def mean_eq6(self) -> float:
        return float(np.mean(list(self.eq6_pct.values())))

    def mean_eq6_without_miss(self) -> float:
        return float(np.mean(list(self.eq6_without_miss_pct.values())))


@dataclasses.dataclass
class Round:
    friction: Friction
    effects: Dict[str, float]
    baseline: HeldOutScore
    candidates: List[CandidateResult]  # ranked, best first
    accepted: Optional[str]
    misfit_p: float  # today's model's final-position misfit against the noise
    refit: str = ""  # whether today's model's parameters were refitted this round, or kept (and why)
    ambiguous: List[str] = dataclasses.field(default_factory=list)  # candidates that explain it alike (none accepted)
    partial: Optional[str] = None  # the best candidate, when it helped by less than half (not accepted)
    polished: str = ""  # how the accepted effect's estimate moved after acceptance (_polish)

    def table(self) -> str:
        lines = [f"{'candidate':<32}{'fitted (95% interval)':<44}{'held-out rms':>14}{'gain':>6}{'Wald p':>9}"
                 f"{'dAIC':>7}  status"]
        for c in self.candidates:
            fitted = ", ".join(f"{k}={v:.3g}+-{Z95 * se:.2g}" for k, (v, se) in c.coordinates.items())
            lines.append(f"{c.name:<32}{fitted:<44}{c.held_out_before:>6.2f}->{c.held_out_after:<6.2f}"
                         f"{100 * c.held_out_reduction:>5.0f}%{c.wald_p:>9.2g}{c.aic_delta:>7.0f}  {c.status}")
        return "\n".join(lines)


@dataclasses.dataclass
class Diagnosis:
    campaign: str
    start_friction: Friction
    start_effects: Dict[str, float]
    free: List[str]  # friction coefficients these data identify (the others stay at their start values)
    rounds: List[Round]
    waterfall: List[dict]
    friction: Friction  # the final model
    effects: Dict[str, float]
    accepted: List[str]
    verdict: str
    explanation: str
    misfit_p: float  # the final model's, without the unexplained trials
    not_detectable: List[dict]
    where_it_fails: Optional[dict]
    simulations: int
    wall_s: float
    final_coordinates: Dict[str, List[float]] = dataclasses.field(default_factory=dict)  # name -> [value, se]
    starts: Dict[str, List[float]] = dataclasses.field(default_factory=dict)  # "<trial>:<rate>" -> [value, se]
    stop_reason: str = ""
    unexplained_trials: Dict[str, dict] = dataclasses.field(default_factory=dict)  # trial -> misfit (see Misfit)
    _trials: list = dataclasses.field(default_factory=list, repr=False)
    report: object = dataclasses.field(default=None, repr=False)  # compare.CampaignReport of the final model (plots)

    @property
    def candidates(self) -> List[CandidateResult]:
        return self.rounds[0].candidates if self.rounds else []

    def to_json(self) -> dict:
        return {
            "campaign": self.campaign, "verdict": self.verdict, "explanation": self.explanation,
            "start_model": {"friction": dataclasses.asdict(self.start_friction), "effects": self.start_effects},
            "free_friction": self.free,
            "baseline_error": {"held_out_mean_eq6_pct": self.rounds[0].baseline.mean_eq6(),
                               "cases": self.rounds[0].baseline.by_case(self._trials)} if self.rounds else None,
            "candidates": [dataclasses.asdict(c) for c in self.candidates],
            "rounds": [{"effects": r.effects, "accepted": r.accepted, "misfit_p": r.misfit_p, "refit": r.refit,
                        "polished": r.polished, "ambiguous": r.ambiguous, "partial": r.partial,
                        "candidates": [dataclasses.asdict(c) for c in r.candidates]} for r in self.rounds],
            "accepted_effects": self.accepted,
            "model": {"friction": dataclasses.asdict(self.friction), "effects": self.effects},
            "error_after": self.waterfall[-1] if self.waterfall else None,
            "final_coordinates": self.final_coordinates, "starts": self.starts, "stop_reason": self.stop_reason,
            "waterfall": self.waterfall, "misfit_p": self.misfit_p, "unexplained_trials": self.unexplained_trials, "not_detectable": self.not_detectable,
            "where_it_fails": self.where_it_fails, "simulations": self.simulations, "wall_s": self.wall_s,
        }

    def visibility_table(self) -> str:
        """Per candidate coordinate and case: the final position's change (cm) per probe step."""
        cases = list(dict.fromkeys(t.case for t in self._trials))
        lines = [f"{'coordinate (probe step)':<44}" + "".join(f"{c:>10}" for c in cases)]
        for c in self.candidates:
            keys = [k for k in next(iter(c.visibility.values()), {}) if "final position" in k]
            for k in keys:
                name = k.split(":")[0] + f" ({k.rsplit(' per ', 1)[1]})"
                lines.append(f"{name:<44}" + "".join(f"{c.visibility[case][k]:>10.2f}" for case in cases))
        return "\n".join(lines)

    def waterfall_table(self) -> str:
        """Per case and step: Eq. 6 error, the same with the replay's own miss taken off, yaw-rate fit."""
        cases = list(self.waterfall[0]["cases"]) if self.waterfall else []
        lines = [f"{'':<38}" + "".join(f"{'Eq.6 (miss off) fit':>26}" for _ in cases) + f"{'Eq.6 (miss off)':>20}",
                 f"{'model':<38}" + "".join(f"{c:>26}" for c in cases) + f"{'all trials':>20}"]
        for step in self.waterfall:
            cells = "".join(f"{v['mean_eq6_error_pct']:>9.2f}% ({v['mean_eq6_without_replay_miss_pct']:>6.2f}%)"
                            f"{v['mean_yaw_rate_fit_pct']:>5.0f}%" for v in (step["cases"][c] for c in cases))
            lines.append(f"{step['model']:<38}{cells}{step['mean_eq6_error_pct']:>9.2f}% "
                         f"({step['mean_eq6_without_replay_miss_pct']:>6.2f}%)")
        return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ the loop

def linearize(trials, friction, effects, candidates: List[str], evaluator: Evaluator, *, noise=None,
              input_noise_samples=INPUT_NOISE_SAMPLES, held=(), starts=False) -> Linearization:
    """Residuals at (friction, effects) and their forward-difference columns for the friction
    coefficients, the model's own effects and the candidates (and with `starts`, each trial's start:
    start_coordinates); when `noise` is None, the replays' own error (replay_error: their bias, taken off r0,
    and the input noise)."""
    if starts:  # linearized at the trials' own rates, else the protocol's with the IMU's first yaw rate
        trials = [with_start_guess(t) for t in trials]
    coords = (start_coordinates(trials) if starts else []) + friction_coordinates(friction, held)
    for name in list(dict.fromkeys([*(e.name for e in active(effects)), *candidates])):
        coords += effect_coordinates(name, effects)
    base = evaluator.map(_evaluate, [(t, friction, effects) for t in trials], "residuals at the model")
    jobs, where = [], []
    for c in coords:
        values = [c2.value + (_signed_step(c) if c2 is c else 0.0) for c2 in coords]
        model = model_at(friction, effects, coords, values)
        for k, t in enumerate(trials):
            if c.start_of is not None and c.start_of[0] != k:
                continue  # another trial's start: this trial's replay is base's exactly
            if t.failed_joints or not _acts_in_failed_joints_only(c):  # else the replay is base's exactly
                jobs.append((starts_at(trials, coords, values)[k] if c.start_of else t, *model))
                where.append((c.name, k))
    outputs = evaluator.map(_evaluate, jobs, f"linearizing at the model ({len(coords)} directions)")
    bias = start_bias = None
    if noise is None:
        bias, noise, start_bias = _replay_errors(trials, friction, effects, [b[3] for b in base], [len(b[0]) for b in base],
                                     evaluator, input_noise_samples)
    columns = {c.name: [np.zeros(len(b[0])) for b in base] for c in coords}
    wcolumns = {c.name: [np.zeros(len(b[4])) for b in base] for c in coords}
    for (name, k), o in zip(where, outputs, strict=True):
        step = _signed_step(next(c for c in coords if c.name == name))
        if len(o[0]) == len(base[k][0]):  # a replay that stops elsewhere has no column: 0
            columns[name][k] = (o[0] - base[k][0]) / step
        if len(o[4]) == len(base[k][4]):
            wcolumns[name][k] = (o[4] - base[k][4]) / step
    lin = Linearization(trials=list(trials), friction=friction, effects=dict(effects), coordinates=coords,
                        r0=[b[0] for b in base], eq6=[b[1] for b in base], yaw_fit=[b[2] for b in base],
                        columns=columns, noise=list(noise), bias=bias, ends=[b[3] for b in base],
                        w0=[b[4] for b in base], wcolumns=wcolumns, start_bias=start_bias)
    lin.r0 = [lin.corrected(k, r) for k, r in enumerate(lin.r0)]
    lin.w0 = [lin.start_corrected(k, w) for k, w in enumerate(lin.w0)]
    return lin


def _replay_errors(trials, friction, effects, ends, lengths, evaluator: Evaluator, samples: int) -> tuple:
    """Per trial, the replay's bias (None where the bootstrap does not line up with the trial's residuals of
    `lengths`), its input-noise covariance (replay_error) and the bias of its start rows, at (friction, effects)."""
    # Twins first, then every draw a job of its own: a campaign of a few trials keeps every core busy.
    twins = evaluator.map(bootstrap_twin, [(t, friction, effects, end) for t, end in zip(trials, ends, strict=True)],
                          "the replays' own error: noise-free twins")
    jobs = [(*made, friction, effects, end, k, i) for k, (made, end) in enumerate(zip(twins, ends, strict=True))
            if made is not None for i in range(samples)]
    draws = iter(evaluator.map(bootstrap_draw, jobs, "the replays' own error: the twins replayed with noisy angles"))
    errors = [None if made is None else _draws_mean_and_covariance([next(draws) for _ in range(samples)])
              for made in twins]
    bias, noise, start_bias = [], [], []
    for error, n in zip(errors, lengths, strict=True):
        start_bias.append(None if error is None else error[2])
        if error is None or len(error[0]) != n:
            bias.append(None)
            noise.append(np.zeros((n, n)))
            continue
        bias.append(error[0])
        # The bias is a mean of `samples` draws: taking it off adds 1 / samples of their covariance.
        noise.append(error[1] * (1.0 + 1.0 / samples))
    return bias, noise, start_bias


def _with_replay_error(lin: Linearization, evaluator: Evaluator, samples: int) -> Linearization:
    """`lin` with the replay's bias and input noise measured again at its model (their residuals moved
    from the old bias to the new one, the trial weights recomputed)."""
    bias, noise, start_bias = _replay_errors(lin.trials, lin.friction, lin.effects, lin.ends,
                                             [len(r) for r in lin.r0], evaluator, samples)
    r0 = [r + _moved_bias(before, after, r) for r, before, after in zip(lin.r0, lin.bias or [None] * len(lin.r0), bias,
                                                                         strict=True)]
    w0 = [w + _moved_bias(before, after, w) for w, before, after in zip(
        lin.w0, lin.start_bias or [None] * len(lin.w0), start_bias, strict=True)]
    return dataclasses.replace(lin, r0=r0, bias=bias, noise=noise, weights=trial_weights(lin.trials, noise), w0=w0,
                               start_bias=start_bias)


def _moved_bias(before, after, residual) -> np.ndarray:
    """What moves a residual from one replay bias taken off to another (None: none taken off, or not lined up)."""
    def taken(bias):
        return 0.0 if bias is None or len(bias) != len(residual) else bias
    return taken(before) - taken(after)


def _acts_in_failed_joints_only(c: Coordinate) -> bool:
    if c.owner in ("friction", START):
        return c.name == "c_joint"
    return LIBRARY[c.owner].failed_joints_only


def _signed_step(c: Coordinate) -> float:
    return c.step if c.value + c.step <= c.upper else -c.step


def held_out_by_simulation(lin: Linearization, fitted: Fit, evaluator: Evaluator, label: str) -> HeldOutScore:
    """Every trial replayed with the parameters fitted without it."""
    coords = [lin.coordinate(n) for n in fitted.names]
    jobs = []
    for k in range(len(lin.trials)):
        values = [c.value + d for c, d in zip(coords, fitted.held_out_steps[k], strict=True)]
        jobs.append((starts_at(lin.trials, coords, values)[k], *model_at(lin.friction, lin.effects, coords, values)))
    out = evaluator.map(_evaluate, jobs, f"held-out replays: {label}")
    _, effects = model_at(lin.friction, lin.effects, coords, fitted.values)
    return _score(lin, label, effects, [lin.corrected(k, o[0]) for k, o in enumerate(out)], [o[1] for o in out],
                  [o[2] for o in out])


def screen_friction(lin: Linearization, names=FRICTION_NAMES, max_relative_error=0.3, nuisance=()) -> List[str]:
    """The friction coefficients these data identify (identify.screen's rule: standard error below 30%), fitted
    with the `nuisance` coordinates."""
    if not names:
        return []
    fitted = fit(lin, list(nuisance) + list(names))
    return [n for n, v, se in zip(fitted.names, fitted.values, fitted.standard_errors, strict=True)
            if n in names and se < max_relative_error * abs(v)]


def _visibility(lin: Linearization, name: str) -> Dict[str, Dict[str, float]]:
    """Per case: how much the final position (cm) and the path or yaw-rate channel (standardized RMS)
    change per probe step of each of the candidate's coordinates, averaged over the case's trials."""
    out: Dict[str, Dict[str, float]] = {}
    for c in [c for c in lin.coordinates if c.owner == name]:
        for case in dict.fromkeys(t.case for t in lin.trials):
            ks = [k for k, t in enumerate(lin.trials) if t.case == case]
            cols = [lin.columns[c.name][k] * c.step for k in ks]
            row = out.setdefault(case, {})
            row[f"{c.name}: final position cm per {c.step:g}"] = float(
                np.mean([100 * FINAL_SIGMA_M * np.linalg.norm(col[:2]) for col in cols]))
            row[f"{c.name}: path rms (standardized) per {c.step:g}"] = float(
                np.mean([np.sqrt(np.mean(col[2:] ** 2)) if len(col) > 2 else 0.0 for col in cols]))
    return out


def diagnose(campaign, *, friction: Optional[Friction] = None, effects=None, candidates=None, trials=None,
             held=(), workers=None, scheduler=None, input_noise_samples=INPUT_NOISE_SAMPLES, max_rounds=MAX_ROUNDS,
             probe_study=True, progress=None, start_rates="rest") -> Diagnosis:
    """The loop of the module docstring on `campaign` (its `trials`, all by default), from the model
    (`friction`, `effects`); `candidates` are effect names or groups (effects.candidate_names; by default the
    physical effects, and the potentiometer faults of joints whose readings pass their limit); the friction
    coefficients named in `held` stay at their values (no replays spent on them). The head's rates at t = 0 of a
    trial that does not give them: `start_rates` "rest", the protocol's convention; "fit", three nuisance
    coordinates per trial (start_coordinates) fixed in every fit by its first START_FIT_S (fit), for data whose
    start follows no known convention."""
    from .executor import make_executor

    started = time.perf_counter()
    if start_rates not in START_MODES:
        raise ValueError(f"start_rates must be one of {START_MODES}, got {start_rates!r}")
    friction = friction or Friction()
    chosen = campaign.chosen(trials)
    effects = dict(effects or {})
    names = candidate_names(candidates)
    if candidates is None:  # readings past a joint's limit point at its potentiometer (measurements.limit_warnings)
        names += potentiometer_faults(sorted({j for t in chosen for j in t.beyond_limit}))
    not_detectable = []
    for n in names:
        if not LIBRARY[n].seen_in_replay:
            not_detectable.append({"name": n, "reason": "replays follow the measured joint angles, which already "
                                   "contain it", "experiment": "runs driven by the gait command (rc1 run), compared "
                                   "with the measured joint angles: the servo channel"})
    replayed = [n for n in names if LIBRARY[n].seen_in_replay and n not in [e.name for e in active(effects)]]
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        evaluator = Evaluator(executor, progress)
        lin = linearize(chosen, friction, effects, replayed, evaluator, input_noise_samples=input_noise_samples,
                        held=held, starts=start_rates == "fit")
        nuisance = [c.name for c in lin.coordinates if c.owner == START]
        free = screen_friction(lin, [n for n in FRICTION_NAMES if n not in held], nuisance=nuisance)
        lin = _starts_fitted(lin, nuisance, free, evaluator)
        start = _unrefitted(lin, "start (no refit)")
        start_step = {"model": start.label, "effects": start.effects, "mean_eq6_error_pct": start.mean_eq6(),
                      "mean_eq6_without_replay_miss_pct": start.mean_eq6_without_miss(),
                      "cases": start.by_case(chosen)}
        rounds, accepted, waterfall = [], [], [start_step]
        # In every fit: the trials' starts (nuisance), the free friction, then the accepted effects' parameters.
        model_names = nuisance + list(free)
        stop_reason = f"{max_rounds} rounds"
        for round_index in range(max_rounds):
            if round_index and misfit(lin, lin.r0, len(physics_names(lin, model_names))).consistent:
                # What the accepted effects leave is noise: searching it only finds false alarms (measured:
                # head drag accepted after a true toe, benchmarks/diagnosis.py).
                stop_reason = "what the accepted effects leave is consistent with the noise"
                break
            label = "today's model" if not accepted else "+ " + " + ".join(accepted)
            current = _unrefitted(lin, label + " (no refit)")
            round_names, baseline, refit_note = model_names, current, "nothing to refit"
            if physics_names(lin, model_names):
                base_fit = fit(lin, model_names)
                refit = held_out_by_simulation(lin, base_fit, evaluator, label + ", refitted")
                if round_index == 0:
                    waterfall.append(_step("today's model, friction refitted", refit, chosen))
                if refit.sum_of_squares < current.sum_of_squares:
                    baseline, refit_note = refit, "refitted"
                    # Move today's model to its refit (all trials), where simulation confirms it.
                    moved = _moved(lin, model_names, base_fit.values, evaluator)
                    if lin.weighted_sum_of_squares(moved.r0) < current.sum_of_squares:
                        lin = moved
                    else:
                        refit_note = "refitted for the held-out check; kept where it was (the all-trial refit did worse)"
                else:
                    # The linear step of a nonlinear (Coulomb) model can overshoot: keep what simulation rejects out.
                    round_names = nuisance
                    refit_note = (f"kept: refitting {', '.join(model_names)} raised the held-out sum of squares "
                                  f"from {current.sum_of_squares:.4g} to {refit.sum_of_squares:.4g}")
            base_fit = fit(lin, round_names)
            left = misfit(lin, base_fit.residual, len(physics_names(lin, round_names)))
            results = _rank(lin, base_fit, round_names, [n for n in replayed if n not in accepted])
            # Refine the most promising candidates by one secant step: replay every trial at the candidate's
            # linear fit and update its columns (Broyden) there. A column taken at 0 misjudges effects seen at
            # a clearly visible strength (measured: a 0.5 head drag fitted at the 0.8 trust bound, not
            # significant, and a tilt accepted in its place); the refined fits decide.
            refined = {}
            for c in [c for c in results if c.status != "not detectable here"][:REFINED_CANDIDATES]:
                names = round_names + [co.name for co in lin.coordinates if co.owner == c.name]
                at = _moved(lin, names, fit(lin, names).values, evaluator, what=f"refining {c.name}")
                again = _rank(at, fit(at, round_names), round_names, [c.name], reference=base_fit)[0]
                again.visibility, again.indistinguishable_from = c.visibility, c.indistinguishable_from
                refined[c.name] = (again, at)
            results = sorted([refined[c.name][0] if c.name in refined else c for c in results], key=lambda c: -c.score)
            checked = {}
            for c in [c for c in results if c.status == "candidate" and c.name in refined][:2]:
                at = refined[c.name][1]
                cand_fit = fit(at, round_names + [co.name for co in at.coordinates if co.owner == c.name])
                check = held_out_by_simulation(at, cand_fit, evaluator, f"{label} + {c.name}")
                c.simulated = {"held_out_sum_of_squares_before": baseline.sum_of_squares,
                               "held_out_sum_of_squares_after": check.sum_of_squares,
                               "held_out_reduction": 1.0 - check.sum_of_squares / baseline.sum_of_squares,
                               "held_out_mean_eq6_pct_before": baseline.mean_eq6(),
                               "held_out_mean_eq6_pct_after": check.mean_eq6()}
                checked[c.name] = (c, check, cand_fit, at)
            chosen_name, ambiguous, partial = decide(results)
            winner = checked[chosen_name] if chosen_name else None
            for c in results:
                if c.status == "candidate":
                    c.status = "significant, not checked (a better candidate was)"
            # The ranking: what simulation showed first (by its held-out gain), then the linear scores.
            results.sort(key=lambda c: (c.simulated is None, -(c.simulated or {}).get("held_out_reduction", c.score)))
            rounds.append(Round(friction=lin.friction, effects=dict(lin.effects), baseline=baseline, candidates=results,
                                accepted=winner[0].name if winner else None, misfit_p=left.p, refit=refit_note,
                                ambiguous=ambiguous, partial=partial))
            if winner is None:
                stop_reason = ("candidates these trials cannot tell apart" if ambiguous else
                               f"{partial} explains only part of it" if partial else "no candidate accepted")
                break
            c, check, cand_fit, at = winner
            accepted.append(c.name)
            waterfall.append(_step("+ " + " + ".join(accepted) + " (held out)", check, chosen))
            model_names = list(dict.fromkeys(model_names + cand_fit.names))
            # The accepted model: the refined fit, where its residuals are simulated (at the refinement's point
            # plus the refit's step; that step is small, and the next round refits from there).
            lin = _moved(at, cand_fit.names, cand_fit.values, evaluator)
            # The replay's own error depends on the model. Measured on 2 s joint-2 trials with a 0.5 head drag
            # hidden: with the bias taken at no drag, the accepted true model missed a trial by 5 cm (noise 1.1)
            # and was called unexplained; with the bias taken again here, its misfit is the noise's (p = 0.36).
            lin = _with_replay_error(lin, evaluator, input_noise_samples)
            accepted_at = {n: lin.coordinate(n).value for n in c.coordinates}
            lin, steps = _polish(lin, model_names, c.name, evaluator, input_noise_samples)
            # The accepted effect's interval, with the replay's error measured where it was estimated.
            here = fit(lin, model_names)
            rounds[-1].polished = (f"{steps} Gauss-Newton step(s) from " + ", ".join(
                f"{n}={v:.3g}" for n, v in accepted_at.items()) if steps else "no step: the accepted fit stands")
            for n, se in zip(here.names, here.standard_errors, strict=True):
                if n in c.coordinates:
                    value = lin.coordinate(n).value
                    c.coordinates[n] = [value, float(se)]
                    c.interval95[n] = interval95(value, float(se))
        # The model written is the last one checked by simulation (no unchecked chord step); its parameters'
        # standard errors come from the linearization there.
        friction_out, effects_out = lin.friction, lin.effects
        final_fit = fit(lin, model_names)
        report, where = _where_it_fails(campaign, lin.trials, friction_out, effects_out, evaluator)
        simulated = [lin.corrected(k, trial_residual(t, report.runs[t.trial_id])) for k, t in enumerate(lin.trials)]
        final_coordinates = {n: [float(lin.coordinate(n).value), float(se)] for n, se in zip(
            final_fit.names, final_fit.standard_errors, strict=True)}
        # the final model's replays, not the linear guess
        left = misfit(lin, simulated, len(physics_names(lin, model_names)))
    for r in rounds:
        for c in r.candidates:
            if c.status == "not detectable here" and c.name not in [d["name"] for d in not_detectable]:
                not_detectable.append({"name": c.name, "reason": "its largest physical value would not be "
                                       "significant on these trials", "experiment": c.experiment})
    if probe_study:
        _suggest_experiments(rounds, not_detectable, friction_out, effects_out, workers, progress)
    verdict, explanation = _verdict(accepted, left, rounds)
    return Diagnosis(campaign=str(campaign.path), start_friction=friction, start_effects=dict(effects or {}),
                     free=free, rounds=rounds, waterfall=waterfall, friction=friction_out, effects=effects_out,
                     accepted=accepted, verdict=verdict, explanation=explanation, misfit_p=left.p,
                     unexplained_trials=left.outliers,
                     not_detectable=not_detectable, where_it_fails=where, simulations=evaluator.simulations,
                     wall_s=time.perf_counter() - started, _trials=lin.trials, report=report,
                     final_coordinates={n: v for n, v in final_coordinates.items() if n not in nuisance},
                     starts={n: v for n, v in final_coordinates.items() if n in nuisance}, stop_reason=stop_reason)


def decide(results: List[CandidateResult]) -> tuple:
    """From the candidates checked by simulation (`simulated` set): (the accepted one's name or None, the
    names that explain the held-out trials alike, the name of one that explains only part of it); sets
    every checked candidate's status and the accepted one's flag."""
    helping = [c for c in results if c.simulated and c.simulated["held_out_reduction"] >= MIN_HELD_OUT_REDUCTION]
    helping.sort(key=lambda c: c.simulated["held_out_sum_of_squares_after"])
    for c in results:
        if c.simulated and c not in helping:
            c.status = "no held-out gain when simulated"
    if not helping:
        return None, [], None
    best, others = helping[0], helping[1:]
    for c in others:
        c.status = "held-out gain, clearly less than the best one's"
    best_after = best.simulated["held_out_sum_of_squares_after"]
    rivals = [c for c in others if c.simulated["held_out_sum_of_squares_after"] < AMBIGUOUS_RATIO * best_after]
    if rivals:
        # Two effects that explain the held-out trials alike: these trials cannot tell which it is.
        ambiguous = [best.name] + [c.name for c in rivals]
        for c in [best, *rivals]:
            c.status = "explains it, as well as " + ", ".join(n for n in ambiguous if n != c.name)
        return None, ambiguous, None
    if best.simulated["held_out_reduction"] < ACCEPT_HELD_OUT_REDUCTION:
        # Significant and confirmed, but too weak a gain to name the effect: wrong effects accepted in a true
        # one's place gained 17-49% (ACCEPT_HELD_OUT_REDUCTION).
        best.status = (f"explains part of it ({100 * best.simulated['held_out_reduction']:.0f}% of the held-out "
                       f"error; accepting needs half): not accepted")
        return None, [], best.name
    best.status, best.accepted = "accepted", True
    return best.name, [], None


def _score(lin: Linearization, label: str, effects, corrected, eq6, yaw_fit) -> HeldOutScore:
    """Per-trial scores of one replay per trial of `lin`: its bias-corrected residuals, Eq. 6, yaw-rate fit."""
    ids = [t.trial_id for t in lin.trials]
    return HeldOutScore(label=label, effects=effects, sum_of_squares=lin.weighted_sum_of_squares(corrected),
                        eq6_pct=dict(zip(ids, eq6, strict=True)), yaw_fit_pct=dict(zip(ids, yaw_fit, strict=True)),
                        eq6_without_miss_pct={i: lin.eq6_without_miss(k, r) for k, (i, r) in
                                              enumerate(zip(ids, corrected, strict=True))})


def _unrefitted(lin: Linearization, label: str) -> HeldOutScore:
    """The model of `lin` scored as it stands (its replays there, nothing refitted or held out)."""
    return _score(lin, label, dict(lin.effects), lin.r0, lin.eq6, lin.yaw_fit)


def _cases(trials, eq6, fit_pct, without_miss) -> Dict[str, dict]:
    out: Dict[str, list] = {}
    for t, e, f, m in zip(trials, eq6, fit_pct, without_miss, strict=True):
        out.setdefault(t.case, []).append((e, f, m))
    return {c: {"mean_eq6_error_pct": float(np.mean([v[0] for v in vs])),
                "mean_yaw_rate_fit_pct": float(np.mean([v[1] for v in vs])),
                "mean_eq6_without_replay_miss_pct": float(np.mean([v[2] for v in vs]))} for c, vs in out.items()}


def _step(label, score: HeldOutScore, trials) -> dict:
    return {"model": label, "effects": score.effects, "mean_eq6_error_pct": score.mean_eq6(),
            "mean_eq6_without_replay_miss_pct": score.mean_eq6_without_miss(),
            "held_out_sum_of_squares": score.sum_of_squares, "cases": score.by_case(trials)}


def _starts_fitted(lin: Linearization, nuisance: List[str], free: List[str], evaluator) -> Linearization:
    """`lin` with the trials' starts (`nuisance`) fitted with today's free friction on all trials, where
    simulation confirms it on their start rows (the friction stays: the round's refit moves it)."""
    if not nuisance:
        return lin
    fitted = fit(lin, nuisance + free)
    moved = _moved(lin, nuisance, fitted.values[:len(nuisance)], evaluator, what="the trials' starts fitted")
    return moved if sum(w @ w for w in moved.w0) < sum(w @ w for w in lin.w0) else lin  # what fixes them


def _moved(lin: Linearization, names: List[str], values, evaluator, **kwargs) -> Linearization:
    """`lin` relinearized (_relinearize) where the coordinates `names` take `values` (starts included)."""
    coords = [lin.coordinate(n) for n in names]
    return _relinearize(lin, *model_at(lin.friction, lin.effects, coords, values), evaluator,
                        trials=starts_at(lin.trials, coords, values), **kwargs)


def _relinearize(lin: Linearization, friction, effects, evaluator, what="residuals at the new model",
                 samples=0, trials=None) -> Linearization:
    """The residuals at the new model; the columns updated by Broyden's rank-one secant update along the
    step (no replays: the columns of the coordinates that moved become secants through both points, so
    a nonlinear response is followed); the replay's bias and input noise reused, or with `samples`
    measured again at the new model (replay_error) before the update, so that the secants follow the
    residuals with the replay's own miss taken off. `trials`: the trials with their starts at the new model."""
    trials = list(trials or lin.trials)
    out = evaluator.map(_evaluate, [(t, friction, effects) for t in trials], what)
    # A trial whose replay now stops elsewhere keeps its old residual and columns (and bias and noise).
    stays = [len(o[0]) != len(r) for o, r in zip(out, lin.r0, strict=True)]
    target = lin
    if samples:
        bias, noise, start_bias = _replay_errors(trials, friction, effects, [o[3] for o in out],
                                                 [len(o[0]) for o in out], evaluator, samples)
        old = lin.bias or [None] * len(stays)
        old_start = lin.start_bias or [None] * len(stays)
        bias = [old[k] if s else b for k, (s, b) in enumerate(zip(stays, bias, strict=True))]
        start_bias = [old_start[k] if s else b for k, (s, b) in enumerate(zip(stays, start_bias, strict=True))]
        noise = [lin.noise[k] if s else n for k, (s, n) in enumerate(zip(stays, noise, strict=True))]
        target = dataclasses.replace(lin, bias=bias, noise=noise, weights=trial_weights(lin.trials, noise),
                                     start_bias=start_bias)
    values = _coordinate_values(lin.coordinates, friction, effects, trials)
    step = np.array(values) - np.array([c.value for c in lin.coordinates])
    names = [c.name for c in lin.coordinates]
    columns = {n: list(cols) for n, cols in lin.columns.items()}
    wcolumns = {n: list(cols) for n, cols in lin.wcolumns.items()}
    r0, ends, w0 = [], [], []
    for k, (o, r) in enumerate(zip(out, lin.r0, strict=True)):
        if stays[k]:
            r0.append(r)
            ends.append(lin.ends[k])
            w0.append(lin.w0[k])
            continue
        ends.append(o[3])
        new = target.corrected(k, o[0])
        r0.append(new)
        w0.append(target.start_corrected(k, o[4]) if len(o[4]) == len(lin.w0[k]) else lin.w0[k])
        if step @ step > 0:
            for cols, old, now in ((columns, r, new), (wcolumns, lin.w0[k], w0[-1])):
                jacobian = np.column_stack([cols[n][k] for n in names])
                jacobian += np.outer(now - old - jacobian @ step, step) / (step @ step)
                for j, n in enumerate(names):
                    cols[n][k] = jacobian[:, j]
    coords = [dataclasses.replace(c, value=v) for c, v in zip(lin.coordinates, values, strict=True)]
    return dataclasses.replace(target, trials=trials, friction=friction, effects=dict(effects), coordinates=coords,
                               r0=r0, columns=columns, eq6=[o[1] for o in out], yaw_fit=[o[2] for o in out], ends=ends,
                               w0=w0, wcolumns=wcolumns)


def _polish(lin: Linearization, names: List[str], effect: str, evaluator, samples: int) -> tuple:
    """The accepted model moved by Gauss-Newton steps over `names` (secant columns, each step within the trust
    region, the replay's own error measured again at each point with `samples` draws) while the replays there
    lower the weighted sum of squares and `effect`'s own step exceeds POLISH_TOLERANCE standard errors.
    Acceptance was decided at the bounded refined fit; this only estimates. Measured (3 s `none,J7x2`, seed
    0): a failed joint's 0.6 N m dry friction accepted at 0.40, two trust steps from 0, outside its interval;
    the replays with their own miss taken off fit best at 0.6, but with the miss measured at 0.4 at 0.45-0.48,
    because that miss moves with the friction. Returns the model and the number of steps taken."""
    for k in range(POLISH_STEPS):
        step = fit(lin, names)
        own = [i for i, n in enumerate(step.names) if lin.coordinate(n).owner == effect]
        if all(abs(step.steps[i]) <= POLISH_TOLERANCE * step.standard_errors[i] for i in own):
            break
        moved = _moved(lin, names, step.values, evaluator, what=f"polishing {effect} ({k + 1})", samples=samples)
        if lin.weighted_sum_of_squares(moved.r0) >= lin.weighted_sum_of_squares(lin.r0):  # both with lin's weights
            break
        lin = moved
    else:
        k = POLISH_STEPS
    return lin, k


def _coordinate_values(coords, friction, effects, trials) -> List[float]:
    values = []
    for c in coords:
        if c.owner == START:
            values.append(float(trials[c.start_of[0]].initial_head_rates[c.start_of[1]]))
        elif c.owner == "friction":
            values.append(getattr(friction, c.name))
        else:
            effect = LIBRARY[c.owner]
            values.append(float(effect.coordinates(effect_values(effects, effect))[c.name]))
    return values


def _rank(lin: Linearization, base: Fit, model_names: List[str], names: List[str],
          reference: Optional[Fit] = None) -> List[CandidateResult]:
    """Every candidate fitted with today's model's free parameters, scored on held-out trials (linear)
    against `reference` (today's model without the candidates; `base` by default)."""
    reference = reference or base
    before = lin.weighted_rms(reference.held_out)
    x_model = lin.rows(model_names, range(len(lin.trials)), weighted=True)[0]
    projected = {}
    results = []
    for name in names:
        own = [c.name for c in lin.coordinates if c.owner == name]
        fitted = fit(lin, model_names + own)
        after = lin.weighted_rms(fitted.held_out)
        x_own = lin.rows(own, range(len(lin.trials)), weighted=True)[0]
        projected[name] = _orthogonal_to(x_own, x_model)
        idx = [fitted.names.index(n) for n in own]
        coords = [lin.coordinate(n) for n in own]
        effect = LIBRARY[name]
        values = effect.coordinates(effect_values(lin.effects, effect))
        values.update({n: float(fitted.values[i]) for n, i in zip(own, idx, strict=True)})
        se = {n: float(fitted.standard_errors[i]) for n, i in zip(own, idx, strict=True)}
        p = wald_p(fitted, own)
        reduction = 1.0 - (after / before) ** 2 if before > 0 else 0.0
        detectable = {n: 3.0 * se[n] for n in own}
        visible = any(3.0 * se[n] < max(abs(c.lower), abs(c.upper)) for n, c in zip(own, coords, strict=True)) and \
            np.linalg.norm(projected[name]) > 1e-9
        if not visible:
            status = "not detectable here"
        elif p >= P_ACCEPT:
            status = "not significant"
        elif reduction < MIN_HELD_OUT_REDUCTION:
            status = "no held-out gain"
        else:
            status = "candidate"
        results.append(CandidateResult(
            name=name, parameters=effect.from_coordinates(values),
            coordinates={n: [values[n], se[n]] for n in own},
            interval95={n: interval95(values[n], se[n]) for n in own},
            wald_p=p, held_out_before=before, held_out_after=after, held_out_reduction=reduction,
            aic_delta=fitted.aic - reference.aic, score=reduction, status=status, detectable_strength=detectable,
            visibility=_visibility(lin, name)))
    for c in results:
        for other in results:
            if other is c or np.linalg.norm(projected[c.name]) < 1e-9 or np.linalg.norm(projected[other.name]) < 1e-9:
                continue
            if subspace_cosine(projected[c.name], projected[other.name]) >= INDISTINGUISHABLE_COS:
                c.indistinguishable_from.append(other.name)
    results.sort(key=lambda c: -c.score)
    return results


def _where_it_fails(campaign, trials, friction, effects, evaluator) -> dict:
    from .compare import CampaignReport
    from .residuals import where_it_fails

    out = evaluator.map(_replay_and_score, [(t, friction, effects) for t in trials], "where the model fails")
    report = CampaignReport(campaign=str(campaign.path), friction=friction, trials=[o[0] for o in out],
                            runs={t.trial_id: o[1] for t, o in zip(trials, out, strict=True)})
    return report, where_it_fails(report, campaign).to_json()


def _verdict(accepted, left: Misfit, rounds) -> tuple:
    ambiguous = rounds[-1].ambiguous if rounds else []
    if ambiguous:
        gains = {c.name: c.simulated["held_out_reduction"] for c in rounds[-1].candidates if c.name in ambiguous}
        experiments = sorted({c.experiment for c in rounds[-1].candidates if c.name in ambiguous and c.experiment})
        done = f"accepted {', '.join(accepted)}; then " if accepted else ""
        return "ambiguous", (f"{done}{' or '.join(ambiguous)} explain the held-out trials alike (simulated held-out "
                             f"gains {', '.join(f'{100 * g:.0f}%' for g in gains.values())}): these trials cannot "
                             f"tell them apart" + (f"; {'; '.join(experiments)}" if experiments else ""))
    outliers = ""
    if left.outliers:
        outliers = "; not explained: " + ", ".join(
            f"{k} (final position off by {o['off_cm']:.0f} cm, noise {o['noise_cm']:.1f} cm)" for k, o in left.outliers.items())
    if left.consistent and accepted:
        return "effect_found", (f"accepted {', '.join(accepted)}; what is left is consistent with the noise "
                                f"(final positions p = {left.p:.2g}){outliers}")
    partial = rounds[-1].partial if rounds else None
    if left.consistent and not partial:
        # "Nothing found" says as much as the trials could see: name the strengths they would miss.
        unseen = [f"{k} {v:.2g}" for c in (rounds[-1].candidates if rounds else []) for k, v in
                  c.detectable_strength.items()]
        limits = f"; these trials would miss an effect below (3 standard errors): {', '.join(unseen)}" if unseen else ""
        return "no_missing_effect", (f"no candidate is significant on held-out trials, and the misfit is consistent "
                                     f"with the noise (final positions p = {left.p:.2g}){outliers}{limits}")
    part = ""
    if partial:
        best = next(c for c in rounds[-1].candidates if c.name == partial)
        part = (f"; {partial} is significant and removes {100 * best.simulated['held_out_reduction']:.0f}% of the "
                f"held-out error, too little to name it: these trials cannot identify what is missing")
    helped = f"; {', '.join(accepted)} helped but did not explain it (partial)" if accepted else ""
    return "unexplained", (f"the residual is not explained by any candidate (final positions p = {left.p:.2g})"
                           f"{helped}{part}{outliers}")


# ------------------------------------------------------------------------------------------ the probe study

PROBE_KINDS = {
    "no failure, 140 deg/s": ([], None),
    "no failure, 70 deg/s": ([], 70.0),
    "joint 7 failed": ([7], None),
    "joint 13 failed": ([13], None),
    "joint 2 failed": ([2], None),
}
PROBE_SECONDS = 3.0


def probe_visibility(friction: Friction, effects: Dict[str, float], names: List[str], *, workers=None,
                     seconds: float = PROBE_SECONDS, progress=None) -> Dict[str, Dict[str, dict]]:
    """Which kind of trial sees each candidate: a noise-free `seconds`-long trial of every PROBE_KINDS
    kind is synthesized from the model, replayed, and each candidate coordinate's probe step applied.
    Returns kind -> candidate -> {"final_cm_per_probe", "detectable_strength" (three standard errors of
    one trial with the campaign format's stated noise, no input noise), "columns"}."""
    import tempfile
    from pathlib import Path

    from .config import Gait, Stop
    from .executor import make_executor
    from .measurements import load_campaign
    from .synthesize import Case, Noise, Variation, synthesize_campaign

    design = [Case(list(failed), 1, gait=None if f is None else Gait(frequency_deg_s=f))
              for failed, f in PROBE_KINDS.values()]
    with tempfile.TemporaryDirectory() as tmp:
        synthesize_campaign(tmp, design=design, friction=friction, effects=effects, noise=Noise().scaled(0.0),
                            variation=Variation(0.0, 0.0, 0.0), stop=Stop(line_x_m=None, revolutions=None,
                                                                           time_limit_s=seconds))
        trials = load_campaign(Path(tmp)).trials
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(trials))) as executor:
        lin = linearize(trials, friction, effects, names, Evaluator(executor, progress),
                        noise=[np.zeros((1, 1))] * len(trials))
    out: Dict[str, Dict[str, dict]] = {}
    for kind, (failed, frequency) in PROBE_KINDS.items():
        trial_index = next(k for k, t in enumerate(trials) if t.failed_joints == list(failed)
                           and t.gait.frequency_deg_s == (frequency or Gait().frequency_deg_s))
        for name in names:
            own = [c for c in lin.coordinates if c.owner == name]
            cols = np.column_stack([lin.columns[c.name][trial_index] for c in own])
            norms = np.linalg.norm(cols, axis=0)
            out.setdefault(kind, {})[name] = {
                "final_cm_per_probe": {c.name: float(100 * FINAL_SIGMA_M * np.linalg.norm(cols[:2, i]) * c.step)
                                       for i, c in enumerate(own)},
                "detectable_strength": {c.name: (float(3.0 / norms[i]) if norms[i] > 0 else math.inf)
                                        for i, c in enumerate(own)},
                "columns": cols}
    return out


def _suggest_experiments(rounds, not_detectable, friction, effects, workers, progress) -> None:
    """Fill in, from the probe study, the kind of trial that would see each effect not detectable here
    and that would tell apart candidates these data cannot."""
    if not rounds:
        return
    pairs = {tuple(sorted((c.name, other))) for c in rounds[0].candidates for other in c.indistinguishable_from}
    pairs = sorted(pairs | {tuple(sorted((a, b))) for r in rounds for a in r.ambiguous for b in r.ambiguous if a != b})
    hidden = [d["name"] for d in not_detectable if LIBRARY[d["name"]].seen_in_replay]
    names = list(dict.fromkeys(hidden + [n for pair in pairs for n in pair]))
    if not names:
        return
    study = probe_visibility(friction, effects, names, workers=workers, progress=progress)
    for d in not_detectable:
        if d["name"] not in hidden:
            continue
        best = min(study, key=lambda kind: min(study[kind][d["name"]]["detectable_strength"].values()))
        strength = study[best][d["name"]]["detectable_strength"]
        d["experiment"] = (f"a {best} trial: one {PROBE_SECONDS:g} s trial detects "
                           + ", ".join(f"{k} of {v:.3g}" for k, v in strength.items()) + " (sensor noise only)")
    for a, b in pairs:
        cosines = {kind: subspace_cosine(study[kind][a]["columns"], study[kind][b]["columns"]) for kind in study
                   if np.linalg.norm(study[kind][a]["columns"]) > 0 and np.linalg.norm(study[kind][b]["columns"]) > 0}
        if cosines:
            kind = min(cosines, key=cosines.get)
            text = f"a {kind} trial tells {a} and {b} apart (cosine {cosines[kind]:.2f})"
            for c in [c for r in rounds for c in r.candidates if c.name in (a, b)]:
                c.experiment = text if c.experiment is None else c.experiment + "; " + text
