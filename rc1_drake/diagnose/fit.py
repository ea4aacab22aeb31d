"""Fit (stage 2): bounded weighted linear least squares over coordinates of a Linearization, each trial's start
profiled out on its own start rows, with the sandwich (or trial jackknife) covariance and leave-one-trial-out
predictions; and the model moved to a fit where simulation confirms it."""

import dataclasses
import math

import numpy as np
from scipy.stats import t as student_t

from ..config import Z95
from ..sysid.optimize import bounded_step
from ..sysid.stats import channel_variances, larger_covariance
from .linearize import Linearization, moved

TRUST_STEPS = 4.0  # an effect coordinate's linear fit moves at most this many probe steps per round

# The physics' covariance where the trial jackknife exceeds the sandwich: "direction", the larger of the two in every
# direction (stats.larger_covariance: continuous, free of units); "trace", the one of larger trace, the default before
# 2026-11-29 (a trace adds units: it flipped the shipped toe's interval by a quarter on replays moved by round-off,
# docs/findings.md 2026-11-28 (18), 2026-11-29 (24)).
JACKKNIFE_RULE = "direction"


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
    names: list[str]
    values: np.ndarray  # coordinate values at the fit
    steps: np.ndarray  # d from the linearization point
    standard_errors: np.ndarray
    covariance: np.ndarray
    # the sandwich's (every row independent, with its channel's residual variance and the input noise), before the
    # trial jackknife widened the physics' block: how well the noise lets a coordinate be seen, whether or not the
    # trials agree on the linear model
    noise_standard_errors: np.ndarray
    residual: list[np.ndarray]  # per trial, r0 + X d (linear prediction, all trials)
    held_out: list[np.ndarray]  # per trial, the prediction from the fit without that trial
    held_out_steps: list[np.ndarray]  # per trial, d fitted without it
    aic: float

    def held_out_sum_of_squares(self) -> float:
        return float(sum(float(h @ h) for h in self.held_out))


def _own_start(coords, k: int) -> list[int]:
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
            carry = (
                lin.weights[k]
                * np.column_stack([lin.columns[c.name][k] for c in own])
                @ np.linalg.pinv(big_w[:, : len(own)])
            )
            r[start : start + n] -= carry @ w
            x[start : start + n] -= carry @ big_w[:, len(own) :]
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


def _step_bounds(coords) -> tuple:
    """A fit's bounds on its steps: each coordinate's range, an effect's within TRUST_STEPS probe steps."""
    reach = np.array([math.inf if c.owner == "friction" else TRUST_STEPS * c.step for c in coords])
    lower = np.maximum(np.array([c.lower - c.value for c in coords]), -reach)
    upper = np.minimum(np.array([c.upper - c.value for c in coords]), reach)
    return lower, upper


def fit(lin: Linearization, names: list[str]) -> Fit:
    """Bounded weighted linear least squares over `names` (each trial's rows times its weight; a trial's
    start, where among them, fitted to its first START_FIT_S only: _solve), its covariance (the sandwich
    with channel variances and input noise, or the trial jackknife's where larger: JACKKNIFE_RULE), and
    leave-one-trial-out predictions."""
    coords = [lin.coordinate(n) for n in names]
    lower, upper = _step_bounds(coords)
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
        sigma = np.diag(variance[start : start + n]) + lin.weights[k] ** 2 * lin.noise[k]
        if carry is not None:
            start_variances[k] = _start_rows_variance(lin, coords, k, d)
            sigma = sigma + start_variances[k] * carry @ carry.T
        middle += x[start : start + n].T @ sigma @ x[start : start + n]
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
    noise_se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if len(everything) >= 3 and physics:  # a trial's start is its own: no jackknife
        # The jackknife sees what the sandwich assumes away: correlated residuals within a trial (docs/diagnosis.md).
        steps = np.array(held_steps)[:, physics]
        jackknife = (len(steps) - 1) / len(steps) * (steps - steps.mean(axis=0)).T @ (steps - steps.mean(axis=0))
        block = np.ix_(physics, physics)
        if JACKKNIFE_RULE == "direction":
            cov[block] = larger_covariance(cov[block], jackknife)
        elif np.trace(jackknife) > np.trace(cov[block]):
            cov[block] = jackknife
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if physics:  # a coordinate no row moves (a stop's damping while the stop is off) is bounded by nothing
        unseen = [physics[i] for i in np.flatnonzero(~x.any(axis=0))]
        se[unseen] = noise_se[unseen] = math.inf
    m = len(e)
    aic = m * math.log(max(float(e @ e), 1e-300) / m) + 2 * len(names)
    return Fit(
        names=list(names),
        values=np.array([c.value for c in coords]) + d,
        steps=d,
        standard_errors=se,
        covariance=cov,
        noise_standard_errors=noise_se,
        residual=per_trial,
        held_out=held,
        held_out_steps=held_steps,
        aic=aic,
    )


def case_jackknife(lin: Linearization, names: list[str]) -> np.ndarray | None:
    """The jackknife over the trials' cases (none, J7, J13, J7+bias, ...) of the fit over `names`: each case left
    out in turn and the rest fitted (bounded, starts profiled, as `fit`), (G - 1)/G times the steps' scatter, over
    the physics (a start's rows are zero). Trials of one case share their design and with it any error of the
    model's form (another lab's linkage, its failed joint's law), which leaving one trial out keeps in its twins and
    leaving the case out does not (sysid.stats.uncertainty's jackknife over failed joints, for identify). None
    under three cases."""
    cases = list(dict.fromkeys(t.case for t in lin.trials))
    if len(cases) < 3:
        return None
    coords = [lin.coordinate(n) for n in names]
    lower, upper = _step_bounds(coords)
    steps = np.array(
        [_solve(lin, coords, [k for k, t in enumerate(lin.trials) if t.case != case], lower, upper) for case in cases]
    )
    steps[:, [i for i, c in enumerate(coords) if c.start_of is not None]] = 0.0
    centred = steps - steps.mean(axis=0)
    return (len(cases) - 1) / len(cases) * centred.T @ centred


def _t_over_z(dof: int) -> float:
    """Student's t 97.5% quantile over the normal's at `dof`: a jackknife of G groups has G - 1 degrees of freedom,
    so its +-Z95 interval is this much too short."""
    return float(student_t.ppf(0.975, dof) / Z95)


def reported_standard_errors(lin: Linearization, fitted: Fit) -> np.ndarray:
    """`fitted`'s standard errors as a report gives them: its covariance, or the jackknife over cases (case_jackknife,
    scaled by Student's t at its G - 1 degrees of freedom) where that is larger, in every direction of the physics
    (stats.larger_covariance); a start's, and a coordinate no row moves (infinite), as the fit has them. The
    decisions use the fit's own."""
    jackknife = case_jackknife(lin, fitted.names)
    if jackknife is not None:  # widened to a +-Z95 interval at its degrees of freedom
        jackknife = jackknife * _t_over_z(len({t.case for t in lin.trials}) - 1) ** 2
    se = fitted.standard_errors.copy()
    physics = [i for i, n in enumerate(fitted.names) if lin.coordinate(n).start_of is None and math.isfinite(se[i])]
    if jackknife is None or not physics:
        return se
    block = np.ix_(physics, physics)
    se[physics] = np.sqrt(np.clip(np.diag(larger_covariance(fitted.covariance[block], jackknife[block])), 0.0, None))
    return se


def considered_variance(lin: Linearization, names: list[str], considered: list[str]) -> np.ndarray:
    """Per coordinate of `names`, the variance its linear fit takes from the `considered` coordinates, held at their
    values though known only to a factor e (one standard deviation of their log): each one's uncertainty carried
    through the fit's columns, the trials' starts profiled out as the fit does (a consider covariance, as orbit
    determination carries the parameters it does not estimate). Times s^2, a factor e^s. A start's is left at 0."""
    out = np.zeros(len(names))
    coords = [lin.coordinate(n) for n in names + considered]
    physics = [i for i, c in enumerate(coords[: len(names)]) if c.start_of is None]
    if not considered or not physics:
        return out
    x, _, _, _, _ = _profiled_rows(lin, coords, list(range(len(lin.trials))))
    own, held = x[:, : len(physics)], x[:, len(physics) :]
    carried = -np.linalg.pinv(own) @ held * np.array([c.value for c in coords[len(names) :]])
    out[physics] = np.sum(carried**2, axis=1)
    return out


POLISH_STEPS = 3  # Gauss-Newton steps on an accepted model, while simulation confirms them (polish)


POLISH_TOLERANCE = 0.5  # ... and while the accepted effect's step exceeds this many standard errors


def polish(lin: Linearization, names: list[str], effect, evaluator, samples: int, paired=False) -> tuple:
    """The accepted model moved by Gauss-Newton steps over `names` (secant columns, each step within the trust
    region, the replay's own error measured again at each point with `samples` draws, or `paired` ones) while the
    replays there lower the weighted sum of squares and `effect`'s own step exceeds POLISH_TOLERANCE standard errors.
    Acceptance was decided at the bounded refined fit; this only estimates. Measured (3 s `none,J7x2`, seed
    0): a failed joint's 0.6 N m dry friction accepted at 0.40, two trust steps from 0, outside its interval;
    the replays with their own miss taken off fit best at 0.6, but with the miss measured at 0.4 at 0.45-0.48,
    because that miss moves with the friction. `effect`: a name, or a tuple of names whose steps are watched
    together. Returns the model and the number of steps taken."""
    owners = (effect,) if isinstance(effect, str) else tuple(effect)
    for k in range(POLISH_STEPS):
        step = fit(lin, names)
        own = [i for i, n in enumerate(step.names) if lin.coordinate(n).owner in owners]
        if all(abs(step.steps[i]) <= POLISH_TOLERANCE * step.standard_errors[i] for i in own):
            break
        what = f"polishing {' and '.join(owners)} ({k + 1})"
        there = moved(lin, names, step.values, evaluator, what=what, samples=samples, paired=paired)
        if lin.weighted_sum_of_squares(there.r0) >= lin.weighted_sum_of_squares(lin.r0):  # both with lin's weights
            break
        lin = there
    else:
        k = POLISH_STEPS
    return lin, k


def starts_fitted(lin: Linearization, nuisance: list[str], free: list[str], evaluator) -> Linearization:
    """`lin` with the trials' starts (`nuisance`) fitted with today's free friction on all trials, where
    simulation confirms it on their start rows (the friction stays: the round's refit moves it)."""
    if not nuisance:
        return lin
    fitted = fit(lin, nuisance + free)
    there = moved(lin, nuisance, fitted.values[: len(nuisance)], evaluator, what="the trials' starts fitted")
    return there if sum(w @ w for w in there.w0) < sum(w @ w for w in lin.w0) else lin  # what fixes them
