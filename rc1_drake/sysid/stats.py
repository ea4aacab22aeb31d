"""Statistics of a least-squares fit of standardized residuals: each channel's variance, and the parameters'
standard errors and correlations by the sandwich with the replays' input noise (uncertainty)."""

import dataclasses
import math

import numpy as np
from scipy.stats import chi2

from ..config import Z95, Friction
from .input_noise import INPUT_NOISE_SAMPLES
from .parameters import DEFAULT_PARAMETERS, difference_step, parameter_value, with_values
from .residual import FINAL_CHANNEL


def channel_variances(r, channels, num_parameters: int) -> np.ndarray:
    """Per residual, its channel's variance in standardized units. The residuals are scaled by stated
    uncertainties (config.RESIDUAL_SIGMAS) that are not all equally tight: the camera path's 1 cm scale is
    twice its noise, the final position's 1 cm is all hand-measurement noise. So each channel's variance
    is estimated from its own residuals (degrees of freedom shared in proportion), and the final
    position's may exceed 1 (a misfit larger than the noise) but not fall below it: two numbers a trial
    cannot show that the hand measured better than stated."""
    m = len(r)
    channels = np.zeros(m, dtype=int) if channels is None or len(channels) != m else channels
    variance = np.empty(m)
    for c in np.unique(channels):
        mine = channels == c
        dof = max(mine.sum() * (m - num_parameters) / m, 1.0)
        estimate = float(r[mine] @ r[mine]) / dof
        variance[mine] = max(estimate, 1.0) if c == FINAL_CHANNEL else estimate
    return variance


def sandwich(jac, spread) -> tuple:
    """The least-squares estimate's covariance (J^T J)^-1 J^T S J (J^T J)^-1 for residuals of covariance S
    (`spread`), with (J^T J)^-1 taken on the identifiable subspace; and which coordinates leave that subspace (the
    data do not constrain them)."""
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    keep = sv > 1e-9 * max(sv.max(), 1e-300)
    inv = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    null = np.abs(vt[~keep]).max(axis=0) > 1e-6 if (~keep).any() else np.zeros(jac.shape[1], dtype=bool)
    return inv @ jac.T @ spread @ jac @ inv, null


def larger_covariance(s, j) -> np.ndarray:
    """A covariance at least `s` and at least `j` in every direction, and equal to the larger where one is: with X
    from the generalized eigenproblem j X = s X L (X^T s X = 1), X^-T max(L, 1) X^-1. Unchanged by the coordinates'
    units (each scaled by its larger variance; a tiny ridge makes a singular `s` invertible), symmetric in its two
    arguments, and continuous in both, where the larger of the two traces flips on a change of units."""
    s, j = np.asarray(s, dtype=float), np.asarray(j, dtype=float)
    scale = np.sqrt(np.maximum(np.diag(s), np.diag(j)))
    scale = np.where(scale > 0.0, scale, 1.0)
    s_n, j_n = s / np.outer(scale, scale), j / np.outer(scale, scale)
    w, u = np.linalg.eigh(s_n)
    w = np.maximum(w, 0.0) + 1e-12  # round-off may leave a sandwich a hair indefinite
    root_inv = u / np.sqrt(w)  # s^-1/2 up to a rotation
    lam, v = np.linalg.eigh(root_inv.T @ j_n @ root_inv)
    if lam.max() <= 1.0:
        return s.copy()
    if lam.min() >= 1.0:
        return j.copy()
    back = (u * np.sqrt(w)) @ v  # X^-T
    return np.outer(scale, scale) * ((back * np.maximum(lam, 1.0)) @ back.T)


MAX_RELATIVE_ERROR = 0.3  # a coefficient is identifiable when its standard error is under this share of it
# ... and, where a fit ended, when one more Gauss-Newton step would move it by at most this many standard errors: an
# interval is centred on a least misfit, and a fit stopped short of one (a step's small gain, AVS's last pass, a kink)
# would report one that its own linearization says is off-centre (a step under the fits' resolution aside: their
# smallest step is 1e-3 of a coefficient's log)
MAX_STEP_SE, STEP_RESOLUTION = 1.0, 1e-3


def stopped_short(value: float, standard_error: float, step: float) -> bool:
    """Whether the next Gauss-Newton step `step` would move a coefficient off its interval's centre (MAX_STEP_SE)."""
    return abs(step) > MAX_STEP_SE * standard_error and abs(step) > STEP_RESOLUTION * abs(value)


def why_not_identifiable(
    name: str,
    value: float,
    se: float,
    step: float,
    *,
    bound: str | None,
    max_relative_error: float = MAX_RELATIVE_ERROR,
) -> str | None:
    """Why a coefficient's interval is not given (None where it is): unseen, at a bound of its range, or stopped
    short of its least misfit (uncertainty()'s rules, in that order)."""
    if not math.isfinite(se) or se >= max_relative_error * abs(value):
        return (f"{name}: not identifiable from these trials (relative standard error "
                f"{'inf' if not math.isfinite(se) else f'{100 * se / max(abs(value), 1e-12):.0f}%'}); its value is "
                f"not a fit these trials support")  # fmt: skip
    if bound is not None:
        return (f"{name}: the fit ran to the {'lower' if bound == '<' else 'upper'} bound of its range ({value:.3g}): "
                f"no measurement, the model's form stopped it there")  # fmt: skip
    if stopped_short(value, se, step):
        return (f"{name}: the fit stopped short of its least misfit (the next step would move it {step:+.3g}, "
                f"{abs(step) / se:.1f} standard errors): its interval is not centred on a fit")  # fmt: skip
    return None


def gauss_newton_step(jac, r) -> np.ndarray:
    """The least-squares step -pinv(J) r from residuals `r` with columns `jac` (on the identifiable subspace)."""
    return -np.linalg.lstsq(jac, r, rcond=1e-9)[0]


# A friction coefficient a fit held (its start's screen did not see it) is known only to a factor 2 (one standard
# deviation of its log: a floor's friction is rarely known better before it is measured); the coefficients fitted
# beside it carry that in their intervals, as the diagnosis's do
HELD_LOG_SD = math.log(2.0)


def held_covariance(jac, held_jac, held_values) -> np.ndarray:
    """The covariance the least-squares fit of the columns `jac` takes from coefficients held at `held_values` (their
    columns `held_jac`) though known only to a factor 2 (HELD_LOG_SD of their log): a consider covariance, each held
    coefficient's uncertainty carried through the fit as orbit determination carries the parameters it does not
    estimate."""
    carried = -np.linalg.lstsq(jac, held_jac, rcond=1e-9)[0] * (HELD_LOG_SD * np.abs(np.asarray(held_values)))
    return carried @ carried.T


def trial_jackknife(jac, r, groups) -> np.ndarray | None:
    """The linearized leave-one-trial-out jackknife's covariance of a least-squares step from residuals r (rows
    grouped by trial, `groups`): each trial left out in turn, the step -pinv(J_rest) r_rest on the rest, and
    (G - 1)/G times the scatter of those G steps. It holds what the sandwich assumes away: residuals correlated
    within a trial (a misfit that persists along a path) and trials that ask for different parameters (a model
    whose form is not the truth's). None with fewer than three trials."""
    if groups is None or len(groups) != len(r):
        return None
    labels = np.unique(groups)
    if len(labels) < 3:
        return None
    steps = []
    for g in labels:
        rest = groups != g
        steps.append(-np.linalg.lstsq(jac[rest], r[rest], rcond=1e-9)[0])
    steps = np.array(steps)
    centred = steps - steps.mean(axis=0)
    return (len(labels) - 1) / len(labels) * centred.T @ centred


@dataclasses.dataclass
class Uncertainty:
    names: list[str]
    values: list[float]
    standard_errors: list[float]  # inf where the data do not constrain the coefficient
    correlation: list[list[float]]
    sensitivities: list[float]  # |change of the standardized residuals| for a 1% change (uncertainty())
    identifiable: list[bool]
    residual_rms: float  # of the standardized residuals
    simulations: int
    # the sandwich's standard errors (every row independent), before the trial jackknife widened them where larger
    noise_standard_errors: list[float] = dataclasses.field(default_factory=list)
    # per coefficient, the next Gauss-Newton step from here over what the fit moved and the data see (0 for the rest,
    # and at a start)
    step_to_least_misfit: list[float] = dataclasses.field(default_factory=list)
    # the coefficients the fit held whose uncertainty (HELD_LOG_SD) the fitted ones' intervals carry
    carried: list[str] = dataclasses.field(default_factory=list)

    # per coefficient, why its interval is not given (why_not_identifiable; None where it is)
    reasons: list = dataclasses.field(default_factory=list)

    def warnings(self) -> list[str]:
        """Why each coefficient not called identifiable is not: its reason, or that a fit held it (fit_screened)."""
        reasons = self.reasons or [None] * len(self.names)
        rows = zip(self.names, self.values, self.standard_errors, self.identifiable, reasons, strict=True)
        return [
            why or why_not_identifiable(n, v, se, 0.0, bound=None) or f"{n}: held where the fit started, not fitted"
            for n, v, se, ok, why in rows
            if not ok
        ]

    def table(self) -> str:
        lines = [
            f"{'coefficient':<12}{'value':>10}{'std. error':>12}{'95% interval':>24}{'sensitivity':>13}  identifiable"
        ]
        for n, v, se, s, ok in zip(
            self.names, self.values, self.standard_errors, self.sensitivities, self.identifiable, strict=True
        ):
            ci = "-" if not math.isfinite(se) else f"[{v - Z95 * se:.4g}, {v + Z95 * se:.4g}]"
            lines.append(
                f"{n:<12}{v:>10.4g}{(f'{se:.3g}' if math.isfinite(se) else 'inf'):>12}{ci:>24}{s:>13.3g}  "
                f"{'yes' if ok else 'NO'}"
            )
        return "\n".join(lines)


def uncertainty(
    residuals,
    friction: Friction,
    *,
    parameters=None,
    relative_step=0.05,
    max_relative_error=MAX_RELATIVE_ERROR,
    effects=None,
    input_noise_samples: int = INPUT_NOISE_SAMPLES,
    trial_jackknife_too: bool = True,
    fitted=None,
    fit_end: bool = True,
) -> Uncertainty:
    """Standard errors and correlations of the free parameters from the residual Jacobian at
    (`friction`, `effects`): the sandwich (J^T J)^-1 J^T S J (J^T J)^-1 of least squares with S the
    residual variance of each channel (channel_variances), plus, with `input_noise_samples`, the
    covariance that the angle noise in the replays' input causes (CampaignResiduals.input_noise: that
    many more replays per trial; INPUT_NOISE_SAMPLES by default, 0 leaves it out and understates the
    intervals, docs/findings.md (32)); with `trial_jackknife_too`, over the parameters the fit
    moved (`fitted`, names; all free ones by default) that the noise lets the data see (the sandwich's relative
    standard error under `max_relative_error`), the larger of that and the linearized trial jackknife in every
    direction (trial_jackknife, larger_covariance), as the diagnosis's fit takes it, and of the jackknife over the
    sets of failed joints (`failure_groups`: no failure, J7, J13): trials that share a failed joint share its
    mis-modelled law, a bias the trial jackknife cannot see (findings (34)). The jackknife's steps move only
    those: a direction the data do not see would swing every leave-one-out step along it, and through the
    correlations widen what the data do see. A parameter is identifiable when its relative standard error is below
    `max_relative_error`, it lies inside its bounds and, at a fit's end (`fit_end`), the next Gauss-Newton step over
    what the fit moved and the noise lets the data see would shift it by at most MAX_STEP_SE of its standard error.
    At a screen's start (not `fit_end`) S is the noise's alone (each standardized residual's variance 1, plus the
    input noise): what the data would see, however far the start's replays miss them. Costs one residual evaluation
    per free parameter, plus one.

    The Jacobian is taken in the parameters' own units (forward differences of 5% of the value, at least
    0.5% of the bounds' range for a coefficient, 2% of the range for an effect parameter), not in their
    logarithm: at a coefficient near zero a log-scale column vanishes, and with it the correlation that
    should widen the other coefficients' intervals. Sensitivities are per 1% of a coefficient's value
    (of the range where it is 0, and for effect parameters)."""
    free = [p for p in (parameters or DEFAULT_PARAMETERS) if not p.frozen]
    start_sims = getattr(residuals, "simulations", 0)
    r0 = residuals(friction, effects)
    columns, per_percent = [], []
    for p in free:
        value, span = parameter_value(p.name, friction, effects), p.upper - p.lower
        h = difference_step(p, value, relative_step)
        step = h if value + h <= p.upper else -h
        columns.append((residuals(*with_values(friction, effects, {p.name: value + step})) - r0) / step)
        per_percent.append(0.01 * (abs(value) if p.is_friction and value > 0 else span))
    jac = np.column_stack(columns)
    n = jac.shape[1]
    # at a fit's end the residuals' own variance (a misfit beyond the noise widens the intervals); at a start the
    # noise's (1 a standardized residual): a far start's misfit would hide from the screen what the data see
    variances = channel_variances(r0, getattr(residuals, "channels", None), n) if fit_end else np.ones(len(r0))
    spread = np.diag(variances)
    if input_noise_samples and hasattr(residuals, "input_noise"):
        spread = spread + residuals.input_noise(friction, effects, samples=input_noise_samples)
    cov, null = sandwich(jac, spread)
    noise_se = [math.inf if null[i] else float(math.sqrt(max(cov[i, i], 0.0))) for i in range(n)]
    values = [parameter_value(p.name, friction, effects) for p in free]
    moved = set(fitted) if fitted is not None else {p.name for p in free}
    seen = [i for i, p in enumerate(free) if p.name in moved and noise_se[i] < max_relative_error * abs(values[i])]
    for by in ("groups", "failure_groups") if trial_jackknife_too and seen else ():
        jackknife = trial_jackknife(jac[:, seen], r0, getattr(residuals, by, None))
        if jackknife is not None:
            cov[np.ix_(seen, seen)] = larger_covariance(cov[np.ix_(seen, seen)], jackknife)
    held = [i for i, p in enumerate(free) if p.name not in moved and p.is_friction] if fit_end else []
    if held and seen:
        cov[np.ix_(seen, seen)] += held_covariance(jac[:, seen], jac[:, held], [values[i] for i in held])
    se = [math.inf if null[i] else float(math.sqrt(max(cov[i, i], 0.0))) for i in range(n)]
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = np.where(np.outer(d, d) > 0, cov / np.outer(d, d), 0.0)
    step = np.zeros(n)
    if fit_end and seen:  # over what the fit moved and the data see (as the jackknife), the rest held
        step[seen] = gauss_newton_step(jac[:, seen], r0)
    # a coefficient at a bound of its range is no measurement: the model's form, not the data, stopped it there
    reasons = [
        why_not_identifiable(
            p.name, v, s, d, bound=bound_side(v, p.lower, p.upper), max_relative_error=max_relative_error
        )
        for s, v, p, d in zip(se, values, free, step, strict=True)
    ]
    identifiable = [why is None for why in reasons]
    return Uncertainty(
        names=[p.name for p in free],
        values=values,
        standard_errors=se,
        correlation=np.round(corr, 4).tolist(),
        sensitivities=[float(np.linalg.norm(c)) * k for c, k in zip(columns, per_percent, strict=True)],
        identifiable=identifiable,
        residual_rms=float(np.sqrt(np.mean(r0**2))),
        simulations=getattr(residuals, "simulations", 0) - start_sims,
        noise_standard_errors=noise_se,
        step_to_least_misfit=step.tolist(),
        carried=[free[i].name for i in held] if seen else [],
        reasons=reasons,
    )


def interval95(value: float, standard_error: float) -> list[float]:
    return [value - Z95 * standard_error, value + Z95 * standard_error]


Z95_ONE_SIDED = 1.645  # the standard normal's 95% quantile: a one-sided bound


def p_text(p: float, *, bare: bool = False) -> str:
    """'p = 0.0014', and below what double precision resolves (a tail that underflowed to 0) 'p < 1e-300'; `bare`:
    the value alone ('0.0014', '<1e-300'), for a table's column."""
    if p < 1e-300:
        return "<1e-300" if bare else "p < 1e-300"
    return f"{p:.2g}" if bare else f"p = {p:.2g}"


def bound_side(value: float, lower=-math.inf, upper=math.inf) -> str | None:
    """Where `value` sits: "<" at its lower bound, ">" at its upper, None inside [lower, upper]."""
    scale = max(abs(lower) if math.isfinite(lower) else 0.0, abs(upper) if math.isfinite(upper) else 0.0, 1.0)
    return "<" if value <= lower + 1e-9 * scale else ">" if value >= upper - 1e-9 * scale else None


def reported_interval(value: float, standard_error: float, lower=-math.inf, upper=math.inf) -> tuple[float, float]:
    """The 95% interval a report states: value +- Z95 se inside [lower, upper]; at a bound one-sided, open on the
    bound's side (value + Z95_ONE_SIDED se at the lower, value - it at the upper), where the fit's clipped
    linearization gives no two-sided interval."""
    side = bound_side(value, lower, upper)
    if side is None:
        return value - Z95 * standard_error, value + Z95 * standard_error
    if side == "<":
        return -math.inf, value + Z95_ONE_SIDED * standard_error
    return value - Z95_ONE_SIDED * standard_error, math.inf


def estimate_text(name: str, value: float, standard_error: float, lower=-math.inf, upper=math.inf) -> str:
    """'name=v+-h' (95%); at a bound of [lower, upper] one-sided, 'name=0 (at its bound; < 0.12 at 95%)'
    (reported_interval), and no interval at all when the data do not move it off."""
    scale = max(abs(lower) if math.isfinite(lower) else 0.0, abs(upper) if math.isfinite(upper) else 0.0, 1.0)
    side = bound_side(value, lower, upper)
    if side is None:
        return f"{name}={value:.3g}+-{Z95 * standard_error:.2g}"
    if not math.isfinite(standard_error) or standard_error <= 1e-9 * scale:
        return f"{name}={value:.3g} (at its bound)"
    low, high = reported_interval(value, standard_error, lower, upper)
    return f"{name}={value:.3g} (at its bound; {side} {high if side == '<' else low:.2g} at 95%)"


def wald_p(fitted, names: list[str]) -> float:
    """p-value of the Wald test that the parameters `names` of a fit (its .names, .values, .covariance) are 0
    (chi-squared, one dof per parameter)."""

    idx = [fitted.names.index(n) for n in names]
    value = fitted.values[idx]
    cov = fitted.covariance[np.ix_(idx, idx)]
    stat = float(value @ np.linalg.pinv(cov) @ value) if np.any(np.diag(cov) > 0) else 0.0
    return float(chi2.sf(stat, len(idx)))
