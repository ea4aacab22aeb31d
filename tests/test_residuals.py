"""Residual statistics (where the model fails): the whiteness and correlation kernels against series of
known structure, and a hidden tilted floor showing up as a growing path error."""

import numpy as np

from rc1_drake.residuals import correlation, lag1, ljung_box


def _ar1(rho, n, seed):
    rng = np.random.default_rng(seed)
    x = np.zeros(n)
    for k in range(1, n):
        x[k] = rho * x[k - 1] + rng.normal()
    return x


def test_ljung_box_tells_white_noise_from_a_correlated_series():
    white = np.random.default_rng(0).normal(size=2000)
    assert abs(lag1(white)) < 0.05 and ljung_box(white)[1] > 0.01
    correlated = _ar1(0.8, 2000, 1)
    assert abs(lag1(correlated) - 0.8) < 0.05 and ljung_box(correlated)[1] < 1e-10
    # Q by hand for a short series: x = [1, -1, 1, -1]: rho_1 = -3/4, rho_2 = 2/4; Q(2) = 4*6*(9/16/3 + 4/16/2)
    q, _ = ljung_box([1.0, -1.0, 1.0, -1.0], lags=2)
    assert abs(q - 4 * 6 * (0.5625 / 3 + 0.25 / 2)) < 1e-12


def test_correlation_discounts_autocorrelated_residuals():
    rng = np.random.default_rng(2)
    x = rng.normal(size=500)
    r, p = correlation(0.5 * x + rng.normal(size=500), x)
    assert abs(r - 0.5 / np.sqrt(1.25)) < 0.05 and p < 1e-10
    smooth = _ar1(0.95, 500, 3)
    drift = _ar1(0.95, 500, 4)  # independent of `smooth`, but both slow: naive tests find spurious links
    r, p = correlation(smooth, drift)
    n = 500
    naive_t = abs(r) * np.sqrt((n - 2) / (1 - r * r))
    from scipy.stats import t as student

    assert p > 2 * student.sf(naive_t, n - 2)
    assert correlation(np.ones(10), np.arange(10.0)) == (0.0, 1.0)


def test_a_hidden_wheel_toe_shows_as_a_growing_path_error(tmp_path):
    """The same 3 s no-failure trial with and without a 2 deg wheel toe, replayed by the paper's model:
    with the toe the camera-path error grows several times faster and passes 2 cm at least twice as early. (A tilted
    floor would not show here: the replayed snake follows its measured angles almost kinematically.)"""
    from rc1_drake.compare import compare_campaign
    from rc1_drake.config import Stop
    from rc1_drake.measurements import load_campaign
    from rc1_drake.residuals import where_it_fails
    from rc1_drake.synthesize import Case, synthesize_campaign

    growth = {}
    for name, effects in (("plain", {}), ("toe", {"wheel_toe_deg": 2.0})):
        synthesize_campaign(
            tmp_path / name,
            design=[Case([], 1)],
            seed=6,
            effects=effects,
            stop=Stop(line_x_m=None, revolutions=None, time_limit_s=3.0),
        )
        campaign = load_campaign(tmp_path / name)
        (row,) = where_it_fails(compare_campaign(campaign, workers=1), campaign).trials
        growth[name] = row
    assert growth["toe"].position_error_growth_m_s > 3 * abs(growth["plain"].position_error_growth_m_s)
    toe_at, plain_at = growth["toe"].exceeds_2cm_at_s, growth["plain"].exceeds_2cm_at_s
    assert toe_at is not None and (plain_at is None or plain_at > 2 * toe_at)
    assert set(growth["plain"].correlations) == {
        "heading_sin",
        "heading_cos",
        "lateral_slip",
        "gait_phase_sin",
        "gait_phase_cos",
    }
