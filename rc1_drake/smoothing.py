"""The cubic smoothing spline of measured joint angles, its weight chosen by generalized
cross-validation (GCV) in O(n).

The spline minimizes sum (y_i - f(x_i))^2 + lam * integral f''(x)^2 dx: scipy's make_smoothing_spline
with `lam` given, a natural cubic spline with knots at the samples. scipy's own GCV search evaluates
the influence matrix's trace in Python loops (about 1 s per joint of a 10 s trial); here the same
GCV score, n |y - f|^2 / tr(I - A)^2, comes from the Reinsch form (Green & Silverman 1994, ch. 2-3):
with h the sample spacings, Q the (n, n-2) second-difference matrix and R the (n-2, n-2) tridiagonal
matrix, B = R + lam Q'Q (pentadiagonal), gamma = B^-1 Q'y, y - f = lam Q gamma and
tr(I - A) = lam tr(B^-1 Q'Q), whose needed bands of B^-1 the Hutchinson-de Hoog recursion gives from
B's banded LDL' factors. Compiled by numba: about 0.1 ms per evaluation for 1000 samples.
"""

import numpy as np
from numba import njit
from scipy.interpolate import make_smoothing_spline
from scipy.optimize import minimize_scalar

LOG10_LAM_BOUNDS = (-15.0, 5.0)  # lam in s^3: from interpolation to a straight line, for samples 0.01-0.1 s apart


@njit(cache=True)
def _reinsch(h, y, lam):
    """The Reinsch form's solve: Q's columns (a, b, c), Q'Q's bands (d0, d1, d2), B's LDL' factors (d, l1, l2),
    gamma = B^-1 Q'y (the spline's second derivatives at the inner samples) and Q gamma (= (y - f) / lam)."""
    n = len(y)
    m = n - 2
    # Column i of Q has a[i], b[i], c[i] in rows i, i+1, i+2.
    a = 1.0 / h[:m]
    c = 1.0 / h[1 : m + 1]
    b = -a - c
    qty = a * y[:m] + b * y[1 : m + 1] + c * y[2:]
    # The bands of Q'Q and of B = R + lam Q'Q: main diagonal, first and second off-diagonals.
    d0 = a * a + b * b + c * c
    d1 = np.zeros(m)
    d2 = np.zeros(m)
    d1[: m - 1] = b[: m - 1] * a[1:] + c[: m - 1] * b[1:]
    d2[: m - 2] = c[: m - 2] * a[2:]
    e0 = (h[:m] + h[1 : m + 1]) / 3.0 + lam * d0
    e1 = np.zeros(m)
    e1[: m - 1] = h[1:m] / 6.0 + lam * d1[: m - 1]
    e2 = lam * d2
    # B = L D L', L unit lower triangular with l1[i] = L[i+1, i], l2[i] = L[i+2, i].
    d = np.empty(m)
    l1 = np.zeros(m)
    l2 = np.zeros(m)
    for i in range(m):
        s = e0[i]
        if i >= 1:
            s -= l1[i - 1] ** 2 * d[i - 1]
        if i >= 2:
            s -= l2[i - 2] ** 2 * d[i - 2]
        d[i] = s
        if i + 1 < m:
            t = e1[i]
            if i >= 1:
                t -= l1[i - 1] * l2[i - 1] * d[i - 1]
            l1[i] = t / s
        if i + 2 < m:
            l2[i] = e2[i] / s
    z = np.empty(m)
    for i in range(m):
        s = qty[i]
        if i >= 1:
            s -= l1[i - 1] * z[i - 1]
        if i >= 2:
            s -= l2[i - 2] * z[i - 2]
        z[i] = s
    gamma = np.empty(m)
    for i in range(m - 1, -1, -1):
        s = z[i] / d[i]
        if i + 1 < m:
            s -= l1[i] * gamma[i + 1]
        if i + 2 < m:
            s -= l2[i] * gamma[i + 2]
        gamma[i] = s
    residual = np.zeros(n)
    residual[:m] += a * gamma
    residual[1 : m + 1] += b * gamma
    residual[2:] += c * gamma
    return d0, d1, d2, d, l1, l2, gamma, residual


@njit(cache=True)
def gcv_terms(h, y, lam):
    """(|y - f|^2, tr(I - A)) of the smoothing spline with weight lam at samples spaced by h."""
    m = len(y) - 2
    d0, d1, d2, d, l1, l2, _, residual = _reinsch(h, y, lam)
    rss = lam * lam * float(residual @ residual)
    # Bands of S = B^-1 (Hutchinson-de Hoog): S = D^-1 L^-1 + (I - L') S, from the last row up.
    s0 = np.zeros(m + 2)
    s1 = np.zeros(m + 2)
    s2 = np.zeros(m + 2)
    for i in range(m - 1, -1, -1):
        p = l1[i] if i + 1 < m else 0.0
        q = l2[i] if i + 2 < m else 0.0
        s2[i] = -p * s1[i + 1] - q * s0[i + 2]
        s1[i] = -p * s0[i + 1] - q * s1[i + 1]
        s0[i] = 1.0 / d[i] - p * s1[i] - q * s2[i]
    trace = float(np.sum(s0[:m] * d0) + 2.0 * np.sum(s1[:m] * d1) + 2.0 * np.sum(s2[:m] * d2))
    return rss, lam * trace


@njit(cache=True)
def spline_samples(h, y, lam):
    """The smoothing spline's values f and slopes f' at the samples: f = y - lam Q gamma, and the natural
    cubic's slope from its values and second derivatives (0 at the ends) on each interval."""
    n = len(y)
    _, _, _, _, _, _, gamma, residual = _reinsch(h, y, lam)
    f = y - lam * residual
    second = np.zeros(n)
    second[1 : n - 1] = gamma
    slope = np.empty(n)
    for i in range(n - 1):
        slope[i] = (f[i + 1] - f[i]) / h[i] - h[i] * (2.0 * second[i] + second[i + 1]) / 6.0
    slope[n - 1] = (f[n - 1] - f[n - 2]) / h[n - 2] + h[n - 2] * (second[n - 2] + 2.0 * second[n - 1]) / 6.0
    return f, slope


def gcv_lambda(x, y) -> float:
    """The weight lam that minimizes the GCV score of the smoothing spline of y(x)."""
    h, n = np.diff(np.asarray(x, dtype=float)), len(y)
    y = np.asarray(y, dtype=float)

    def score(log10_lam):
        rss, trace = gcv_terms(h, y, 10.0**log10_lam)
        return n * rss / trace**2

    return float(10.0 ** minimize_scalar(score, bounds=LOG10_LAM_BOUNDS, method="bounded", options={"xatol": 1e-4}).x)


def smoothing_spline(x, y):
    """The GCV cubic smoothing spline of y(x) (a scipy BSpline)."""
    return smoothing_fit(x, y)[0]


def smoothed_samples(x, y) -> tuple:
    """(values, slopes, noise variance) of the GCV cubic smoothing spline of y(x) at the samples x: what
    smoothing_fit's spline gives there, without building the spline."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    lam = gcv_lambda(x, y)
    h = np.diff(x)
    rss, trace = gcv_terms(h, y, lam)
    values, slopes = spline_samples(h, y, lam)
    return values, slopes, rss / trace


def smoothed_about_wave(x, y, omega: float) -> tuple:
    """smoothed_samples of y(x) about its least-squares wave c0 + c1 sin(omega x) + c2 cos(omega x): the spline's
    curvature penalty then acts on what departs from the gait's wave (paper Eqs. 3, 7), not on the wave itself,
    whose curvature it would shrink in proportion to the weight the noise makes GCV choose (a partial spline, Green &
    Silverman 1994 ch. 4). Linear in y, it reproduces a constant, and GCV's weight does not move with an offset or a
    scale of y, as for smoothed_samples. The wave's two extra degrees of freedom are left out of the noise variance
    (a 10 s trial at 50 Hz: 0.4% low)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    basis = np.column_stack([np.ones_like(x), np.sin(omega * x), np.cos(omega * x)])
    c = np.linalg.lstsq(basis, y, rcond=None)[0]
    wave = basis @ c
    values, slopes, variance = smoothed_samples(x, y - wave)
    return values + wave, slopes + omega * (c[1] * np.cos(omega * x) - c[2] * np.sin(omega * x)), variance


def smoothing_fit(x, y) -> tuple:
    """(the GCV cubic smoothing spline of y(x), the samples' noise variance |y - f|^2 / tr(I - A)): the
    residuals' mean square alone is low by the degrees of freedom the spline spends (Green & Silverman
    1994, sec. 3.4)."""
    lam = gcv_lambda(x, y)
    rss, trace = gcv_terms(np.diff(np.asarray(x, dtype=float)), np.asarray(y, dtype=float), lam)
    return make_smoothing_spline(x, y, lam=lam), rss / trace
