"""The O(n) GCV of the smoothing spline against a dense, independent computation: the influence matrix
built column by column from scipy's smoother."""

import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline

from rc1_drake.smoothing import (
    gcv_lambda,
    gcv_terms,
    smoothed_about_wave,
    smoothed_samples,
    smoothing_fit,
    smoothing_spline,
)


def _dense(x, y, lam):
    n = len(x)
    influence = np.column_stack([make_smoothing_spline(x, np.eye(n)[k], lam=lam)(x) for k in range(n)])
    residual = y - influence @ y
    return float(residual @ residual), n - float(np.trace(influence))


@pytest.fixture
def samples():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.uniform(0.05, 0.15, 60))  # uneven spacing, as a logger's
    return x, np.sin(x) + 0.2 * rng.normal(size=60)


@pytest.mark.parametrize("lam", [1e-9, 1e-6, 1e-4, 1e-2])
def test_gcv_terms_match_the_dense_influence_matrix(samples, lam):
    x, y = samples
    rss, trace = gcv_terms(np.diff(x), y, lam)
    dense_rss, dense_trace = _dense(x, y, lam)
    assert rss == pytest.approx(dense_rss, rel=1e-6) and trace == pytest.approx(dense_trace, rel=1e-6)


def test_gcv_lambda_minimizes_the_dense_score(samples):
    x, y = samples

    def score(lam):
        rss, trace = _dense(x, y, lam)
        return len(x) * rss / trace**2

    lam = gcv_lambda(x, y)
    assert 1e-6 < lam < 1e2  # an interior minimum: neither interpolation nor a straight line
    assert score(lam) <= min(score(lam * 1.5), score(lam / 1.5))


def test_the_smoothed_angle_is_closer_to_the_truth_than_the_samples():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 10.0, 0.01)
    truth = np.radians(38) * np.sin(2.44 * t)
    noise = np.radians(0.25)
    spline = smoothing_spline(t, truth + rng.normal(0, noise, len(t)))
    assert np.sqrt(np.mean((spline(t) - truth) ** 2)) < 0.5 * noise
    assert (
        np.abs(spline.derivative()(t) - np.radians(38) * 2.44 * np.cos(2.44 * t))[50:-50].max() < 0.05
    )  # 3% of the peak rate


def test_the_noise_estimate_counts_the_splines_degrees_of_freedom():
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 3.0, 0.01)
    truth = np.radians(38) * np.sin(2.44 * t + 0.3)
    noise = np.radians(0.25)
    estimates, naive = [], []
    for _ in range(40):
        y = truth + rng.normal(0, noise, len(t))
        spline, variance = smoothing_fit(t, y)
        estimates.append(variance)
        naive.append(np.mean((y - spline(t)) ** 2))
    assert np.sqrt(np.mean(estimates)) == pytest.approx(noise, rel=0.03)  # unbiased (40 x 300 samples)
    assert np.sqrt(np.mean(naive)) < 0.97 * noise  # the residuals' RMS alone is low


def test_samples_of_the_spline_match_scipys_spline_values_and_slopes():
    """smoothed_samples (Reinsch form, compiled) against scipy's make_smoothing_spline at the same weight:
    the same natural cubic smoothing spline, so the same values and slopes at the samples, ends included."""
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.005, 0.015, 400))
    y = np.sin(3 * t) + 0.3 * t + rng.normal(0, 0.01, len(t))
    values, slopes, variance = smoothed_samples(t, y)
    spline, expected_variance = smoothing_fit(t, y)
    np.testing.assert_allclose(values, spline(t), atol=1e-9)
    np.testing.assert_allclose(slopes, spline.derivative()(t), atol=1e-6)
    assert variance == pytest.approx(expected_variance, rel=1e-9)


def test_about_the_gait_wave_the_spline_no_longer_shrinks_it():
    """A 30 deg gait wave at 140 deg/s, 10 s at 50 Hz, 0.2 deg of noise, 20 draws: the spline of the angles alone
    shrinks the wave (its error's mean over the draws, the systematic part, is 0.016 deg RMS: enough to turn a replay
    3.5 cm over 3 m, docs/findings.md (33)); about the wave that part is the draws' own scatter of the mean, and each
    draw's error is a third."""
    t, omega = np.arange(0.0, 10.0, 0.02), np.radians(140.0)
    truth = np.radians(30.0) * np.sin(omega * t - 0.7) + 0.01
    errors = {"angles": [], "about the wave": []}
    for seed in range(20):
        y = truth + np.random.default_rng(seed).normal(0.0, np.radians(0.2), len(t))
        errors["angles"].append(smoothed_samples(t, y)[0] - truth)
        errors["about the wave"].append(smoothed_about_wave(t, y, omega)[0] - truth)
    inner = slice(25, -25)  # the ends: a natural spline's own boundary error
    systematic = {k: np.sqrt(np.mean(np.mean(e, axis=0)[inner] ** 2)) for k, e in errors.items()}
    total = {k: np.sqrt(np.mean(np.array(e) ** 2)) for k, e in errors.items()}
    assert systematic["about the wave"] < systematic["angles"] / 3
    assert total["about the wave"] < total["angles"] / 2


def test_about_the_wave_the_smoothing_is_linear_and_keeps_offsets_and_scales():
    """What replay.JointReference.read_back relies on: the reference of gain * angle + offset is gain times the
    angle's reference plus the offset (GCV's weight moves with neither), its slopes gain times the angle's."""
    t, omega = np.arange(0.0, 6.0, 0.01), np.radians(140.0)
    y = np.radians(38.0) * np.sin(omega * t) + np.random.default_rng(3).normal(0.0, np.radians(0.25), len(t))
    values, slopes, variance = smoothed_about_wave(t, y, omega)
    moved, moved_slopes, moved_variance = smoothed_about_wave(t, 1.04 * y + 0.05, omega)
    np.testing.assert_allclose(moved, 1.04 * values + 0.05, atol=1e-9)
    np.testing.assert_allclose(moved_slopes, 1.04 * slopes, atol=1e-8)
    assert moved_variance == pytest.approx(1.04**2 * variance, rel=1e-6)
