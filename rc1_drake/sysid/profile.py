"""Profile-likelihood intervals of a least-squares fit's parameters: each parameter walked out from the fit, the others
profiled at every step, where the sum of squares is not quadratic in it (a coefficient the data bound on one side
only, a fit far from where the data are) and the Wald interval's symmetric reach misleads.

The profile of parameter k: p(v) = min over the others |r(v, others)|^2, from replays: at each v the others start
where the nearest value walked left them, take one Gauss-Newton step of their columns at the fit (within their bounds,
each by at most a factor 2, or a tenth of its range), and keep it where the replays confirm it (OthersRefitted: two
replays a value, never a linear extrapolation, which far from the fit finds fits no replay has). Its
deviance p(v) - min p is taken in the units of the interval the fit reports (`sysid.stats.uncertainty`: the sandwich
with each channel's variance, widened by the jackknives), as a composite likelihood is adjusted for what the
residuals' independence assumes away: times [(J^T J)^-1]_kk / se_k^2, so that where p is quadratic the profile gives
the reported interval, and where it is not, its shape. The interval holds the values whose adjusted deviance is under
chi-squared(1)'s 95% quantile; a side that reaches the parameter's bound below it is open there.
"""

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2

CHI2_95 = float(chi2.ppf(0.95, 1))  # 3.84
# Steps out from the fit, each side: in the log of a positive friction coefficient (e^1.6: 5x), else in shares of the
# bounds' range; the bound itself after the last.
LOG_STEPS = (0.1, 0.25, 0.5, 1.0, 1.6)
RANGE_STEPS = (0.01, 0.03, 0.1, 0.3, 0.6)
# A crossing between two steps is replayed (at most REFINE times a side) until its bracket is within ROOT_RTOL of it: a
# profile that bends between steps (a kink, a saturation) moves it.
REFINE, ROOT_RTOL = 8, 0.005


@dataclasses.dataclass(frozen=True)
class ProfileInterval:
    lower: float
    upper: float
    lower_open: bool  # the deviance stayed under the threshold down to the parameter's lower bound
    upper_open: bool
    points: list  # (value, adjusted deviance) where the profile was taken, by value


def crossing(values, deviances, threshold: float = CHI2_95) -> tuple[float, bool]:
    """(where a walk out from its first point, `values` in order with their adjusted `deviances`, first rises above
    `threshold`, False), interpolated linearly in the root of the deviance (exact where the profile is quadratic in
    the value, as the Wald interval takes it); (its last value, True) where it never does: open there."""
    roots = np.sqrt(np.maximum(np.asarray(deviances, dtype=float), 0.0))
    target = math.sqrt(threshold)
    for a in range(len(roots) - 1):
        if roots[a] <= target < roots[a + 1]:
            t = (target - roots[a]) / (roots[a + 1] - roots[a])
            return float(values[a] + t * (values[a + 1] - values[a])), False
    return float(values[-1]), True


class OthersRefitted:
    """p(v) for one parameter (`name`): |r|^2 of the replays with it at v and the others refitted (the module's
    docstring). `residual_at(values)`: the residuals with the parameters of `values` (name -> value) set; `fit`: every
    parameter's value at the fit; `columns`: the others' (in `fit`'s order, `name` left out); `bounds`: name ->
    (lower, upper, positive)."""

    def __init__(self, residual_at, name: str, fit: dict, columns, bounds: dict):
        self.residual_at, self.name, self.columns, self.bounds = residual_at, name, columns, bounds
        self.others = [n for n in fit if n != name]
        self.left = {fit[name]: np.array([fit[n] for n in self.others])}  # v -> the others where v left them

    def __call__(self, v: float, r=None) -> float:
        base = self.left[min(self.left, key=lambda u: abs(u - v))]
        r = self.residual_at(self._values(v, base)) if r is None else r
        step = np.linalg.lstsq(self.columns, -r, rcond=1e-9)[0] if self.others else np.zeros(0)
        moved = np.array([self._trusted(n, b, b + d) for n, b, d in zip(self.others, base, step, strict=True)])
        there = self.residual_at(self._values(v, moved)) if self.others else r
        better = float(there @ there) < float(r @ r)
        self.left[v] = moved if better else base
        return float(there @ there) if better else float(r @ r)

    def _values(self, v, others) -> dict:
        return {self.name: v, **dict(zip(self.others, map(float, others), strict=True))}

    def _trusted(self, name: str, base: float, value: float) -> float:
        lower, upper, positive = self.bounds[name]
        if positive and base > 0:
            value = min(max(value, 0.5 * base), 2.0 * base)
        else:
            value = min(max(value, base - 0.1 * (upper - lower)), base + 0.1 * (upper - lower))
        return min(max(value, lower), upper)


def deviance_scale(jac, standard_errors, r) -> np.ndarray:
    """Per column of `jac`, [(J^T J)^-1]_kk / se_k^2: how much wider the reported interval is than the unit-noise
    least squares'. Where a column is outside the data's reach or its error infinite, the median of the others, or
    one over the residuals' mean square (their misfit as noise) where none has one."""
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    keep = sv > 1e-9 * max(sv.max(), 1e-300)
    naive = np.einsum("ik,i->k", vt[keep] ** 2, 1.0 / sv[keep] ** 2)
    se = np.asarray(standard_errors, dtype=float)
    ok = np.isfinite(se) & (se > 0) & (naive > 0)
    scale = np.where(ok, naive / np.where(ok, se, 1.0) ** 2, np.nan)
    fallback = float(np.median(scale[ok])) if ok.any() else 1.0 / max(float(np.mean(np.asarray(r) ** 2)), 1.0)
    return np.where(ok, scale, fallback)


def walk(value: float, lower: float, upper: float, positive: bool, side: int) -> list[float]:
    """The values a side's walk takes out from `value` toward its bound (side -1: lower, +1: upper), ending at it."""
    bound = lower if side < 0 else upper
    if positive and value > 0:
        steps = [value * math.exp(side * s) for s in LOG_STEPS]
    else:
        steps = [value + side * s * (upper - lower) for s in RANGE_STEPS]
    inside = [v for v in steps if (v > bound if side < 0 else v < bound)]
    return inside + ([bound] if value != bound else [])


def profile_interval(
    profiled: Callable,
    value: float,
    scale: float,
    lower: float,
    upper: float,
    positive: bool = True,
    threshold: float = CHI2_95,
    r_fit=None,
) -> ProfileInterval:
    """The profile interval of one parameter at `value` (the fit's), `profiled(v)` its profile (OthersRefitted; at
    the fit given its residuals `r_fit`), `scale` its deviance's (deviance_scale). Each side walks out until the
    adjusted deviance, from the least profile seen, passes `threshold`, or to the bound; each end is then replayed
    until it is found within 0.5%. Costs a profile a step: 4-10 where the profile is smooth, up to 28."""
    points = {value: profiled(value, r_fit) if r_fit is not None else profiled(value)}
    for side in (-1, 1):
        for v in walk(value, lower, upper, positive, side):
            points[v] = profiled(v)
            if (points[v] - min(points.values())) * scale > threshold:
                break
    for side in (0, 1):
        _refine(points, profiled, scale, threshold, side)
    (low, low_open), (high, high_open) = _ends(points, scale, threshold)
    least = min(points.values())
    return ProfileInterval(
        lower=low,
        upper=high,
        lower_open=low_open,
        upper_open=high_open,
        points=[(float(x), float((points[x] - least) * scale)) for x in sorted(points)],
    )


def _refine(points: dict, profiled, scale: float, threshold: float, side: int) -> None:
    """Replay `side`'s end (0: lower, 1: upper) until its bracket is within 1% (Brent's method on the root deviance's
    miss of the threshold's: interpolation where the profile is smooth, bisection at a kink between steps)."""
    x, open_side = _ends(points, scale, threshold)[side]
    if open_side:
        return
    xs = sorted(points)
    outside = [v for v in xs if (v < x if side == 0 else v > x)]
    b = outside[-1] if side == 0 else outside[0]
    a = xs[xs.index(b) + (1 if side == 0 else -1)]
    least = min(points.values())

    def miss(v):
        if v not in points:
            points[v] = profiled(v)
        return math.sqrt(max(points[v] - least, 0.0) * scale) - math.sqrt(threshold)

    brentq(miss, a, b, rtol=ROOT_RTOL, xtol=1e-12, maxiter=REFINE, full_output=True, disp=False)


def _ends(points: dict, scale: float, threshold: float) -> tuple:
    """The profile's two ends, (value, open) each, from its points so far (value -> profiled sum of squares)."""
    xs = sorted(points)
    least = min(points.values())
    dev = [(points[x] - least) * scale for x in xs]
    best = int(np.argmin(dev))
    return crossing(xs[best::-1], dev[best::-1], threshold), crossing(xs[best:], dev[best:], threshold)
