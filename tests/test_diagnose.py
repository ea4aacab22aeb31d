"""Finding the missing physics. The linear machinery (bounded fit, held-out predictions, Wald test, misfit
test, look-alike detection) against hand-built data; the replay's own error (a noise-free trial is its own
twin, and its replay's miss is all bias); then the user's demand, data with a hidden effect: a visible
effect (a wheel toe on no-failure and joint-7 trials, a head drag on circling joint-2 trials, a failed
joint's dry friction and a longitudinal friction asymmetry on 3 s joint-7 trials, a lateral one on turning
trials) is found, ranked first and accepted with its parameter inside its interval and the held-out error
at least halved; an effect that other candidates explain about as well on these trials (a head drag, a
payload: named among them) gets no other effect accepted in its place; effects the replays cannot see (a
servo lag, a Stribeck breakaway, a lab floor's tilt) are reported as not detectable here and nothing else
is accepted; a campaign
without a hidden effect gets nothing accepted; an effect outside the library gets no confident wrong
answer. (All effects over many seeds and strengths: benchmarks/diagnosis.py.)"""

import dataclasses
import importlib
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rc1_drake.config import FRICTION_NAMES, Z95, Friction, Gait, Stop
from rc1_drake.diagnose import THRESHOLDS, diagnose
from rc1_drake.diagnose import fit as fit_module
from rc1_drake.diagnose import verdict as verdicts
from rc1_drake.diagnose.coordinates import START, effect_coordinates, friction_coordinates, model_at
from rc1_drake.diagnose.decide import decide
from rc1_drake.diagnose.fit import bounded_least_squares, considered_variance, fit
from rc1_drake.diagnose.linearize import (
    PAIRED_DRAWS,
    Linearization,
    linearize,
    relinearize,
    trial_weights,
    with_replay_error,
)
from rc1_drake.diagnose.loop import (
    FAILED_JOINT_LAW,
    failed_joint_law_effects,
    far_friction,
    needs_friction_search,
    worse_without_failures,
)
from rc1_drake.diagnose.replays import evaluate
from rc1_drake.diagnose.report import CandidateResult, HeldOutScore, Round
from rc1_drake.diagnose.significance import Misfit, final_misfit, misfit, subspace_cosine
from rc1_drake.effects import LIBRARY, Effect, EffectParameter, register
from rc1_drake.measurements import Trial, load_campaign
from rc1_drake.synthesize import Case, Noise, noise_free_twin, synthesize_campaign
from rc1_drake.sysid.evaluate import Evaluator
from rc1_drake.sysid.input_noise import replay_error
from rc1_drake.sysid.parameters import Parameter
from rc1_drake.sysid.stats import larger_covariance, wald_p

REPO = Path(__file__).resolve().parents[1]

# ------------------------------------------------------------------------------------------ linear machinery


def test_ground_slope_coordinates_round_trip():
    slope = LIBRARY["ground_slope"]
    coords = slope.coordinates({"ground_slope_deg": 5.0, "ground_slope_direction_deg": 120.0})
    assert coords["ground_slope_x_deg"] == pytest.approx(5 * math.cos(math.radians(120)))
    assert coords["ground_slope_y_deg"] == pytest.approx(5 * math.sin(math.radians(120)))
    back = slope.from_coordinates(coords)
    assert back["ground_slope_deg"] == pytest.approx(5.0) and back["ground_slope_direction_deg"] == pytest.approx(120.0)


def test_the_tilt_is_searched_within_a_lab_floor_unless_the_model_has_a_ramp():
    level = {c.name: (c.lower, c.upper) for c in effect_coordinates("ground_slope", {})}
    assert level == {"ground_slope_x_deg": (-5.0, 5.0), "ground_slope_y_deg": (-5.0, 5.0)}
    ramp = {
        c.name: (c.value, c.lower, c.upper)
        for c in effect_coordinates("ground_slope", {"ground_slope_deg": 8.0, "ground_slope_direction_deg": 180.0})
    }
    assert ramp["ground_slope_x_deg"] == pytest.approx((-8.0, -8.0, 5.0))  # the known ramp stays inside the search
    assert ramp["ground_slope_y_deg"][1:] == (-5.0, 5.0)


def test_model_at_writes_friction_and_effects_through_their_coordinates():
    coords = friction_coordinates(Friction())[:2] + effect_coordinates("ground_slope", {})
    friction, effects = model_at(Friction(), {"wheel_toe_deg": 1.0}, coords, [0.1, 2.0, 0.0, -3.0])
    assert (friction.c_joint, friction.mu_lat, friction.mu_long) == (0.1, 2.0, Friction().mu_long)
    assert effects["wheel_toe_deg"] == 1.0  # the model's other effects stay
    assert effects["ground_slope_deg"] == pytest.approx(3.0) and effects["ground_slope_direction_deg"] == pytest.approx(
        -90
    )


def test_bounded_least_squares_matches_lstsq_and_respects_bounds():
    rng = np.random.default_rng(0)
    x, d_true = rng.normal(size=(40, 3)), np.array([0.5, -1.0, 2.0])
    r = -x @ d_true
    free = bounded_least_squares(x, r, np.full(3, -10.0), np.full(3, 10.0))
    assert free == pytest.approx(d_true, abs=1e-6)
    capped = bounded_least_squares(x, r, np.full(3, -10.0), np.array([10.0, 10.0, 1.0]))
    assert capped[2] == pytest.approx(1.0, abs=1e-8)
    # With the third held at 1, the first two are the least squares of the rest (by hand: lstsq).
    expected = np.linalg.lstsq(x[:, :2], -(r + x[:, 2]), rcond=None)[0]
    assert capped[:2] == pytest.approx(expected, abs=1e-6)
    assert bounded_least_squares(np.zeros((5, 1)), np.ones(5), -np.ones(1), np.ones(1)) == pytest.approx([0.0])


def _linearization(columns, r0, noise_sd=0.0, trials=4):
    """A hand-built Linearization of `trials` trials of 12 residuals each: two coordinates."""
    kinds = ["none", "J7"] * trials
    fakes = [
        dataclasses.replace(_FAKE_TRIAL, trial_id=f"t{k}", failed_joints=[] if kinds[k] == "none" else [7])
        for k in range(trials)
    ]
    coords = [Parameter("a", -5, 5, value=0.0, step=0.1), Parameter("b", -5, 5, owner="effect", value=0.0, step=1.0)]
    return Linearization(
        trials=fakes,
        friction=Friction(),
        effects={},
        coordinates=coords,
        r0=r0,
        eq6=[0.0] * trials,
        yaw_fit=[0.0] * trials,
        columns=columns,
        noise=[np.eye(12) * noise_sd**2 for _ in range(trials)],
    )


_FAKE_TRIAL = Trial(
    trial_id="t",
    failed_joints=[],
    gait=Gait(),
    stop=None,
    initial_head_pose=np.zeros(3),
    final_head_xy=np.ones(2),
    t=np.zeros(2),
    q=np.zeros((2, 13)),
    head_yaw_rate=np.zeros(2),
)


def test_a_coordinate_no_residual_moves_has_an_unbounded_interval_not_a_zero_one():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(4, 12))
    lin = _linearization({"a": list(a), "b": list(np.zeros((4, 12)))}, list(-0.7 * a + 0.01 * rng.normal(size=(4, 12))))
    fitted = fit(lin, ["a", "b"])
    assert np.isfinite(fitted.standard_errors[0]) and fitted.standard_errors[0] > 0
    assert fitted.standard_errors[1] == fitted.noise_standard_errors[1] == math.inf


def test_fit_recovers_a_linear_truth_and_its_held_out_predictions_are_exact():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(4, 12)), rng.normal(size=(4, 12))
    lin = _linearization({"a": list(a), "b": list(b)}, list(-(0.7 * a - 1.3 * b)))  # noise-free: d = (0.7, -1.3)
    fitted = fit(lin, ["a", "b"])
    assert fitted.values == pytest.approx([0.7, -1.3], abs=1e-6)
    assert all(np.abs(h).max() < 1e-5 for h in fitted.held_out)  # leave-one-out of an exact model: exact
    only_a = fit(lin, ["a"])
    assert only_a.held_out_sum_of_squares() > 1.0  # the missing column shows on held-out trials


@pytest.mark.parametrize("rule", ["trace", "direction"])
def test_trials_that_disagree_widen_the_interval_by_the_jackknife_but_not_the_noises_standard_error(rule, monkeypatch):
    """Three trials say b = 1, a fourth says b = -3, each within noise 0.05: the jackknife over trials sees the
    disagreement as a trial's, the sandwich (rows independent) as rows' scatter only. The interval takes the
    jackknife (by either fit.JACKKNIFE_RULE); how well the noise lets b be seen (Thresholds.detectable_by_noise) the
    sandwich. Trials that agree: the two are one."""
    monkeypatch.setattr(fit_module, "JACKKNIFE_RULE", rule)
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(4, 12)), rng.normal(size=(4, 12))
    noise = 0.05 * rng.normal(size=(4, 12))
    says = np.array([1.0, 1.0, 1.0, -3.0])
    lin = _linearization({"a": list(a), "b": list(b)}, list(-says[:, None] * b + noise), noise_sd=0.05)
    split = fit(lin, ["b"])
    assert split.standard_errors[0] > 3 * split.noise_standard_errors[0]
    agreeing = _linearization({"a": list(a), "b": list(b)}, list(-b + noise), noise_sd=0.05)
    agreed = fit(agreeing, ["b"])
    assert agreed.values[0] == pytest.approx(1.0, abs=0.05)
    assert agreed.standard_errors[0] == agreed.noise_standard_errors[0]


def test_by_direction_the_fits_covariance_bounds_the_jackknife_and_each_noise_standard_error(monkeypatch):
    """Two coordinates, the trials agreeing on a and split on b (three say 1, a fourth -3): by JACKKNIFE_RULE
    "direction" the physics' covariance is at least the trial jackknife's in every direction (computed here from the
    fit's leave-one-trial-out steps) and each standard error at least the noise's, where a choice of the whole block
    by trace hands it the jackknife's alone."""
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(4, 12)), rng.normal(size=(4, 12))
    noise = 0.05 * rng.normal(size=(4, 12))
    says = np.array([1.0, 1.0, 1.0, -3.0])
    lin = _linearization({"a": list(a), "b": list(b)}, list(-a - says[:, None] * b + noise), noise_sd=0.05)
    monkeypatch.setattr(fit_module, "JACKKNIFE_RULE", "direction")
    fitted = fit(lin, ["a", "b"])
    steps = np.array(fitted.held_out_steps)
    jackknife = 0.75 * (steps - steps.mean(axis=0)).T @ (steps - steps.mean(axis=0))
    assert np.linalg.eigvalsh(fitted.covariance - jackknife).min() > -1e-12 * np.abs(jackknife).max()
    assert np.all(fitted.standard_errors >= fitted.noise_standard_errors * (1 - 1e-9))
    monkeypatch.setattr(fit_module, "JACKKNIFE_RULE", "trace")
    by_trace = fit(lin, ["a", "b"])
    assert np.allclose(by_trace.covariance, jackknife)  # the split on b made the whole block the jackknife's


def test_the_larger_covariance_bounds_both_in_every_direction_whatever_the_units():
    """stats.larger_covariance(S, J): at least S and at least J in every direction (M - S, M - J positive
    semidefinite); S where J is smaller everywhere and J where larger; the same whichever comes first; unchanged by
    the coordinates' units (D S D, D J D -> D M D), which a choice by trace is not; and continuous: two covariances
    of equal trace and different shapes give each coordinate the larger of its two variances, or more."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        n = int(rng.integers(1, 5))
        a, b = rng.normal(size=(n, n)), rng.normal(size=(n, n))
        s, j = a @ a.T, b @ b.T
        m = larger_covariance(s, j)
        tol = 1e-9 * np.abs(m).max()
        assert np.linalg.eigvalsh(m - s).min() > -tol and np.linalg.eigvalsh(m - j).min() > -tol
        np.testing.assert_allclose(larger_covariance(j, s), m, rtol=1e-7, atol=tol)
        d = np.diag(10.0 ** rng.uniform(-3, 3, n))
        np.testing.assert_allclose(larger_covariance(d @ s @ d, d @ j @ d), d @ m @ d, rtol=1e-6, atol=tol)
        np.testing.assert_array_equal(larger_covariance(s, 0.5 * s), s)
        np.testing.assert_array_equal(larger_covariance(s, 2.0 * s), 2.0 * s)
    s, j = np.diag([1.0, 0.01]), np.diag([0.02, 0.99])  # traces 1.01 and 1.01: a trace picks one, and by a hair
    np.testing.assert_allclose(larger_covariance(s, j), np.diag([1.0, 0.99]))
    singular = larger_covariance(np.diag([1.0, 0.0]), np.array([[0.5, 0.1], [0.1, 0.3]]))  # a coordinate S cannot see
    assert singular[1, 1] == pytest.approx(0.3) and singular[0, 0] >= 1.0


def test_a_trials_start_is_fitted_to_its_start_rows_and_the_physics_to_all_rows():
    """Noise-free, linear: the fit recovers the physics and every trial's start exactly (held-out predictions
    too); then a misfit along a trial's start columns in its later rows (what a missing effect's drift looks
    like) leaves that trial's start where its start rows put it, as the start's definition says."""
    rng = np.random.default_rng(3)
    n_trials, rows, start_rows = 4, 30, 20
    lin = _linearization(
        {"a": list(rng.normal(size=(n_trials, 12))), "b": list(rng.normal(size=(n_trials, 12)))},
        [np.zeros(12)] * n_trials,
        trials=n_trials,
    )
    starts = [
        Parameter(f"t{k}:{i}", -1.0, 1.0, owner=START, value=0.0, step=1.0, start_of=(k, i))
        for k in range(n_trials)
        for i in range(3)
    ]
    coords = [lin.coordinates[0], *starts]

    def column(c, k, size):  # a start moves its own trial only
        return rng.normal(size=size) if c.start_of is None or c.start_of[0] == k else np.zeros(size)

    columns = {c.name: [column(c, k, rows) for k in range(n_trials)] for c in coords}
    wcolumns = {c.name: [column(c, k, start_rows) for k in range(n_trials)] for c in coords}
    truth = np.r_[0.7, rng.uniform(-0.5, 0.5, 3 * n_trials)]
    names = [c.name for c in coords]

    def at_truth(cols):
        return [-np.column_stack([cols[n][k] for n in names]) @ truth for k in range(n_trials)]

    lin = dataclasses.replace(
        lin,
        coordinates=coords,
        columns=columns,
        r0=at_truth(columns),
        w0=at_truth(wcolumns),
        wcolumns=wcolumns,
        noise=[np.zeros((rows, rows))] * n_trials,
    )
    fitted = fit(lin, names)
    assert fitted.values == pytest.approx(truth, abs=1e-9)
    assert all(np.abs(h).max() < 1e-9 for h in fitted.held_out)
    drift = np.column_stack([columns[f"t0:{i}"][0] for i in range(3)]) @ np.array([0.3, -0.2, 0.1])
    drifted = fit(dataclasses.replace(lin, r0=[lin.r0[0] + drift, *lin.r0[1:]]), names).values
    own = np.column_stack([wcolumns[f"t0:{i}"][0] for i in range(3)])
    by_hand = np.linalg.lstsq(own, -(lin.w0[0] + wcolumns["a"][0] * drifted[0]), rcond=None)[0]
    assert drifted[1:4] == pytest.approx(by_hand, abs=1e-9)  # its start rows' fit, at the physics fitted
    assert np.abs(drifted[1:4] - truth[1:4]).max() < 0.1 * np.abs([0.3, -0.2, 0.1]).max()  # the drift stays out


def test_wald_test_finds_a_real_effect_and_not_a_null_one():
    rng = np.random.default_rng(3)
    a, b, noise = rng.normal(size=(4, 12)), rng.normal(size=(4, 12)), rng.normal(size=(4, 12))
    columns = {"a": list(a), "b": list(b)}
    real = fit(_linearization(columns, list(-(0.5 * a + 2.0 * b) + noise)), ["a", "b"])
    null = fit(_linearization(columns, list(-0.5 * a + noise)), ["a", "b"])
    assert wald_p(real, ["b"]) < 1e-6
    assert wald_p(null, ["b"]) > 0.01


def test_final_position_misfit_is_uniform_under_the_noise_and_small_beyond_it():
    rng = np.random.default_rng(4)
    ps = []
    for _ in range(200):
        r0 = [rng.normal(size=12) * math.sqrt(1.0 + 0.5**2) for _ in range(4)]
        ps.append(
            final_misfit(_linearization({"a": [np.zeros(12)] * 4, "b": [np.zeros(12)] * 4}, r0, noise_sd=0.5), r0, 0)[2]
        )
    assert 0.35 < np.mean(ps) < 0.65 and np.mean(np.array(ps) < 0.05) < 0.12  # uniform: mean 0.5, 5% below 0.05
    big = [rng.normal(size=12) * 4 for _ in range(4)]
    assert final_misfit(_linearization({"a": [np.zeros(12)] * 4, "b": [np.zeros(12)] * 4}, big), big, 0)[2] < 1e-3


def test_trials_whose_replays_move_with_the_input_noise_weigh_less_in_the_fit():
    rng = np.random.default_rng(6)
    a = list(rng.normal(size=(4, 12)))
    r0 = [-0.5 * col for col in a]
    r0[1] = r0[1] + 30.0 * a[1]  # a J7 trial (odd index) far off: its case's replays are noisy (variance 3)
    lin = _linearization({"a": a, "b": [np.zeros(12)] * 4}, r0)
    lin.noise = [np.eye(12) * (3.0 if k % 2 else 0.0) for k in range(4)]
    lin.weights = trial_weights(lin.trials, lin.noise)
    assert lin.weights == pytest.approx([1.0, 0.5, 1.0, 0.5])  # 1 / sqrt(1 + 3)
    w = np.repeat(lin.weights, 12)
    x, r = np.concatenate(a), np.concatenate(r0)
    expected = np.linalg.lstsq((w * x)[:, None], -(w * r), rcond=None)[0][0]  # weighted least squares by hand
    assert fit(lin, ["a"]).values[0] == pytest.approx(expected, abs=1e-6)


def test_two_models_that_call_a_trial_differently_noisy_compare_on_their_likelihood():
    """The likelihood of residuals of variance 1 / w^2 (a trial's weight): with unit weights the sum of squares; over
    a trial's weight it is largest where 1 / w^2 is the residuals' own mean square, so a model that calls a trial
    noisier than its residuals are pays for it, and one that calls it as noisy as they are gains."""
    rng = np.random.default_rng(9)
    r0 = [3.0 * rng.normal(size=400), rng.normal(size=400)]
    lin = _linearization({"a": [np.zeros(400)] * 2}, r0)
    lin.weights = np.ones(2)
    assert lin.neg2_log_likelihood(r0) == pytest.approx(lin.weighted_sum_of_squares(r0))
    scale = np.linspace(0.05, 1.0, 400)
    cost = [lin.neg2_log_likelihood(r0) for lin.weights in ([w, 1.0] for w in scale)]
    assert scale[int(np.argmin(cost))] == pytest.approx(1.0 / np.sqrt(np.mean(r0[0] ** 2)), abs=0.01)
    assert min(cost[0], cost[-1]) > min(cost) + 100  # calling it far noisier, or as quiet as the other, costs


def test_a_few_outlying_trials_are_named_and_the_rest_tested_without_them():
    rng = np.random.default_rng(7)
    residual = [rng.normal(size=12) for _ in range(20)]
    columns = {"a": [np.zeros(12)] * 20, "b": [np.zeros(12)] * 20}
    residual[3][:2] = [40.0, -30.0]  # 50 cm off where the noise is 1 cm
    left = misfit(_linearization(columns, residual, trials=20), residual, 0)
    assert list(left.outliers) == ["t3"] and left.outliers["t3"]["off_cm"] == pytest.approx(50.0) and left.consistent
    for k in (5, 8, 11):  # four of twenty: the campaign's misfit, not a few trials'
        residual[k][:2] = [40.0, 0.0]
    left = misfit(_linearization(columns, residual, trials=20), residual, 0)
    assert len(left.outliers) == 4 and not left.consistent


def _checked(name, after, before=100.0):
    """A candidate checked by simulation: held-out sum of squares `before` -> `after`."""
    return CandidateResult(
        name=name,
        parameters={},
        coordinates={},
        interval95={},
        wald_p=1e-5,
        held_out_before=1.0,
        held_out_after=1.0,
        held_out_reduction=0.0,
        aic_delta=-10.0,
        score=0.0,
        status="candidate",
        simulated={
            "held_out_sum_of_squares_before": before,
            "held_out_sum_of_squares_after": after,
            "held_out_reduction": 1.0 - after / before,
        },
    )


def _round(candidates, **decision):
    baseline = HeldOutScore(
        label="today's model", effects={}, sum_of_squares=100.0, eq6_pct={}, yaw_fit_pct={}, eq6_without_miss_pct={}
    )
    return Round(
        friction=Friction(),
        effects={},
        baseline=baseline,
        candidates=candidates,
        accepted=decision.get("accepted"),
        misfit_p=0.5,
        ambiguous=decision.get("ambiguous", []),
        partial=decision.get("partial"),
    )


@pytest.mark.parametrize(
    "afters, decision",
    [
        ((30.0, 80.0), ("a", [], None)),  # 70% and clearly ahead of the runner-up: accepted
        ((30.0, 40.0), (None, ["a", "b"], None)),  # a runner-up within 1.5x: these trials cannot tell them apart
        ((60.0, 95.0), (None, [], "a")),  # significant and confirmed, but less than half: explains part only
        ((95.0, 120.0), (None, [], None)),  # under 10% (and worse): no gain
    ],
)
def test_an_effect_is_accepted_only_when_it_halves_the_held_out_error_and_no_rival_comes_close(afters, decision):
    candidates = [_checked(n, a) for n, a in zip("ab", afters, strict=True)]
    assert decide(candidates) == decision
    assert [c.accepted for c in candidates] == [decision[0] == "a", False]


def test_when_two_candidates_tie_a_third_checked_one_is_reported_as_clearly_behind():
    candidates = [_checked("a", 30.0), _checked("b", 40.0), _checked("c", 60.0)]
    assert decide(candidates) == (None, ["a", "b"], None)
    assert candidates[2].status == "held-out gain, clearly less than the best one's"


@pytest.mark.parametrize(
    "loose_after, decision",
    [
        (35.0, (None, ["a", "b"], None)),  # a loose look-alike within 1.5x of the best significant one: a tie
        (20.0, (None, ["a", "b"], None)),  # better than it: a tie too, never accepted in its place
        (80.0, ("a", [], None)),  # clearly behind: the significant one is accepted
    ],
)
def test_a_look_alike_that_is_not_significant_can_tie_but_never_be_accepted(loose_after, decision):
    significant, loose = _checked("a", 30.0), _checked("b", loose_after)
    loose.wald_p, loose.status = 0.01, "not significant"
    assert decide([significant, loose]) == decision
    assert not loose.accepted
    if decision[0] == "a":
        assert loose.status == "not significant"


def test_a_rival_fitted_at_a_bound_of_its_range_is_set_aside_only_in_the_variant_that_says_so():
    """A true toe (70% gain) tied by a longitudinal asymmetry run to its bound (60%): today's rule calls them alike;
    with set_aside_at_bound the one at its bound is neither rival nor accepted, and the toe is accepted."""
    from rc1_drake.diagnose.thresholds import Thresholds

    def pair():
        toe, tied = _checked("wheel_toe", 30.0), _checked("longitudinal_friction_asymmetry", 40.0)
        tied.at_bound = ["longitudinal_friction_asymmetry_ratio"]
        return toe, tied

    assert decide(list(pair())) == (None, ["wheel_toe", "longitudinal_friction_asymmetry"], None)
    toe, tied = pair()
    assert decide([toe, tied], Thresholds(set_aside_at_bound=True)) == ("wheel_toe", [], None)
    assert tied.status.startswith("fitted at a bound of its range (longitudinal_friction_asymmetry_ratio)")
    assert not tied.accepted


def test_without_a_significant_candidate_a_helping_look_alike_decides_nothing():
    loose = _checked("b", 20.0)
    loose.wald_p = 0.01
    assert decide([loose]) == (None, [], None)
    assert not loose.accepted


def test_a_partial_explanation_is_reported_and_never_called_found_or_nothing():
    quiet, loud = Misfit(p=0.5, outliers={}), Misfit(p=1e-6, outliers={})
    partial = _checked("head_drag", 60.0)
    verdict, text = verdicts.verdict([], quiet, [_round([partial], partial="head_drag")])
    assert verdict == "unexplained" and "head_drag" in text and "40%" in text
    unseen = _checked("head_drag", 95.0)
    unseen.detectable_strength = {"head_drag_mu": 0.31}
    verdict, text = verdicts.verdict([], quiet, [_round([unseen])])
    assert verdict == "no_missing_effect" and "head_drag_mu 0.31" in text  # what it could have missed
    assert verdicts.verdict(["wheel_toe"], quiet, [_round([], accepted="wheel_toe")])[0] == "effect_found"
    rounds = [_round([], accepted="wheel_toe"), _round([partial], partial="head_drag")]
    verdict, text = verdicts.verdict(["wheel_toe"], loud, rounds)
    assert verdict == "unexplained" and "wheel_toe helped" in text and "head_drag is significant" in text


def test_a_noise_free_trial_is_its_own_twin_and_its_replays_error_is_all_bias(tmp_path):
    silent = dataclasses.replace(Noise().scaled(0.0), camera_dropout=0.0)
    campaign = synthesize_campaign(
        tmp_path,
        design=[Case([], 1), Case([7], 1)],
        seed=3,
        noise=silent,
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=2.0),
    )
    for trial in campaign.trials:
        twin = noise_free_twin(trial, friction=Friction())
        # Equal to rounding: the twin's start heading round-trips through the trial's recorded pose.
        np.testing.assert_allclose(twin.final_head_xy, trial.final_head_xy, rtol=0, atol=1e-12)
        np.testing.assert_allclose(twin.q, trial.q, rtol=0, atol=1e-12)  # NaN (the failed joint) included
        np.testing.assert_allclose(twin.camera, trial.camera, rtol=0, atol=1e-12)
        residual, *_ = evaluate(trial, Friction(), {})
        bias, covariance = replay_error(trial, Friction(), {}, 2, 0)
        # The replay misses its own noise-free trial (measured: 1-2 mm) and the bootstrap sees exactly that:
        # what is left once the bias is off is the potentiometer noise the smoothing finds in clean angles.
        assert np.abs(residual).max() > 0.05
        np.testing.assert_allclose(residual - bias, 0.0, atol=0.02)
        assert np.abs(np.diag(covariance)).max() < 0.02**2


def test_an_estimate_at_its_bound_prints_one_sided_and_a_vanishing_p_value_as_a_bound():
    from rc1_drake.diagnose.coordinates import coordinate_bounds
    from rc1_drake.sysid.stats import Z95_ONE_SIDED, estimate_text, p_text

    assert coordinate_bounds("head_drag_mu") == (0.0, 2.0) and coordinate_bounds("j7_1:start_head_vx_m_s")[0] < -1e300
    assert estimate_text("head_drag_mu", 0.0, 0.07, 0.0, 2.0) == (
        f"head_drag_mu=0 (at its bound; < {Z95_ONE_SIDED * 0.07:.2g} at 95%)"
    )
    assert (
        estimate_text("stribeck_ratio", 3.0, 0.5, 0.0, 3.0)
        == f"stribeck_ratio=3 (at its bound; > {3 - Z95_ONE_SIDED * 0.5:.2g} at 95%)"
    )
    assert estimate_text("g", -0.5, 1.2e-16, -0.5, 0.5) == "g=-0.5 (at its bound)"  # not '+-1.2e-16'
    assert estimate_text("wheel_toe_deg", 2.05, 0.047, -10.0, 10.0) == f"wheel_toe_deg=2.05+-{Z95 * 0.047:.2g}"
    assert p_text(0.0) == "p < 1e-300" and p_text(0.0, bare=True) == "<1e-300" and p_text(1.4e-3) == "p = 0.0014"


def test_the_verdicts_measured_rates_count_where_each_verdict_held():
    """effect_found holds where exactly the hidden effects were accepted; no_missing_effect where nothing was
    hidden; unexplained and ambiguous where something was."""
    rows = [
        {"verdict": "effect_found", "outcome": "right", "hidden": "library"},
        {"verdict": "effect_found", "outcome": "wrong", "hidden": "nothing"},
        {"verdict": "no_missing_effect", "outcome": "right", "hidden": "nothing"},
        {"verdict": "no_missing_effect", "outcome": "missed", "hidden": "library"},
        {"verdict": "no_missing_effect", "outcome": "right", "hidden": "outside"},
        {"verdict": "unexplained", "outcome": "right", "hidden": "outside"},
    ]
    rates = verdicts.verdict_rates(rows)
    assert (rates["effect_found"]["campaigns"], rates["effect_found"]["held"]) == (2, 1)
    assert (rates["no_missing_effect"]["campaigns"], rates["no_missing_effect"]["held"]) == (3, 1)
    assert (rates["unexplained"]["campaigns"], rates["unexplained"]["held"]) == (1, 1)
    assert rates["ambiguous"]["campaigns"] == 0
    measured = {"measured": "2026-11-26", "design": "2 trials each", "verdicts": rates}
    assert verdicts.rate_text(verdicts.Verdict.EFFECT_FOUND, measured) == (
        "measured on the paper's design (2 trials each; 2026-11-26): effect_found held (the hidden effects exactly) "
        "on 1 of 2 campaigns"
    )
    assert "none yet" in verdicts.rate_text(verdicts.Verdict.AMBIGUOUS, measured)
    assert "none yet" in verdicts.rate_text(verdicts.Verdict.AMBIGUOUS, {})


def test_subspace_cosine():
    x = np.random.default_rng(5).normal(size=(30, 2))
    assert subspace_cosine(x[:, :1], 3 * x[:, :1]) == pytest.approx(1.0)
    assert subspace_cosine(x[:, :1], x) == pytest.approx(1.0)  # inside the span
    q, _ = np.linalg.qr(x)
    assert subspace_cosine(q[:, :1], q[:, 1:]) == pytest.approx(0.0, abs=1e-12)


# ------------------------------------------------------------------------------------- hidden-effect campaigns

SECONDS = 2.0
DESIGN = [Case([], 1), Case([7], 2)]  # the nominal gait sees the wheels; a failed joint sees the rest


def _campaign(folder, effects, seed=11, design=DESIGN, seconds=SECONDS, truth_model="drake"):
    synthesize_campaign(
        folder,
        design=design,
        effects=effects,
        seed=seed,
        truth_model=truth_model,
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=seconds),
    )
    return load_campaign(folder)


def _diagnose(campaign, **kwargs):
    # Three 2 s trials identify no friction coefficient (docs/identification.md), so the tests
    # hold them at the truth and spend no replays on them; the friction refit is tested in test_identify.
    return diagnose(campaign, friction=Friction(), held=FRICTION_NAMES, workers=2, probe_study=False, **kwargs)


# A wheel's lateral friction asymmetry is flat at 0 on the design above (Coulomb sticking: docs/diagnosis.md) and a toe
# or a tilt explains what it does to straight gaits; turning left and right (a 4 deg bias on every joint,
# Eq. 7), the body slides outward to opposite sides, so the asymmetry changes the two turns differently.
TURNING = [Case([], 2), Case([], 1, bias_deg=4.0), Case([], 1, bias_deg=-4.0)]


# A failed joint's dry friction has a threshold (docs/diagnosis.md): 3 s trials, where 2 s ones tie it with a
# longitudinal asymmetry. It is accepted at 0.40 (two trust steps) and estimated further once accepted (0.60 +- 0.05
# (se)).
# A lateral asymmetry needs turning trials: on one (-4 deg) at 0.8 it was found (0.81 +- 0.02 (se)); on both ways it
# ties with a head drag (the synthesizer had overwritten the +4 deg trial until 2026-11-28: docs/findings.md).
# (A head drag on circling joint-2 trials was found here while the plant clamped the replays' servos at
# 1.19 N m; with replays that follow the measured angles it is not detectable at 0.5-1.0 on 2-3 s trials.)
@pytest.mark.slow
@pytest.mark.parametrize(
    "effect, key, value, design, seed, seconds",
    [
        ("wheel_toe", "wheel_toe_deg", 1.5, DESIGN, 11, SECONDS),
        ("joint_coulomb_friction", "joint_coulomb_Nm", 0.6, DESIGN, 0, 3.0),
        pytest.param(
            "lateral_friction_asymmetry",
            "lateral_friction_asymmetry",
            0.8,
            TURNING,
            0,
            3.0,
            marks=pytest.mark.xfail(
                strict=True,
                reason=(
                    "measured with both turning trials (before 2026-11-28 the synthesizer overwrote the +4 deg one): "
                    "ranked first at 0.64 +- 0.23, ambiguous with a head drag (48% / 35%); with one -4 deg trial "
                    "found (docs/findings.md)"
                ),
            ),
        ),
    ],
)
def test_a_visible_hidden_effect_is_ranked_first_accepted_and_recovered(
    tmp_path, effect, key, value, design, seed, seconds
):
    result = _diagnose(_campaign(tmp_path, {key: value}, seed=seed, design=design, seconds=seconds))
    first = result.candidates[0]
    assert first.name == effect and first.accepted, result.rounds[0].table()
    assert result.accepted[0] == effect and result.verdict == "effect_found", result.explanation
    estimate, se = first.coordinates[key]
    assert abs(estimate - value) < Z95 * se, (estimate, se)
    # The final model: its 95% interval holds the truth and not 0 (a fixed tolerance, 20% once, asked more than
    # these short trials know: the head drag's 0.39 +- 0.17 (se) failed it).
    final, final_se = result.final_coordinates[key]
    assert abs(final - value) < Z95 * final_se < abs(final), (final, final_se)
    assert final == pytest.approx(result.effects[key])
    assert first.simulated["held_out_sum_of_squares_after"] <= 0.5 * first.simulated["held_out_sum_of_squares_before"]
    # Eq. 6 of a 2 s trial has a floor: the hand's 1 cm (mean |error| 1.25 cm in the plane) over ~0.4 m.
    floor = np.mean([100 * 0.0125 / np.linalg.norm(t.final_head_xy - t.initial_head_pose[:2]) for t in result.trials])
    for eq6 in ("mean_eq6_without_replay_miss_pct", "mean_eq6_error_pct"):
        after, before = result.waterfall[-1][eq6], result.waterfall[-2][eq6]
        assert after - floor <= 0.5 * (before - floor), (eq6, before, after, floor)  # the error above the floor halved
    # The report leads with the answer: the verdict, what was added with its interval, the error before and after.
    verdict, rate, added, error, left = result.format().splitlines()[:5]
    assert verdict.startswith("verdict: effect_found: accepted " + effect)
    assert rate.startswith(("measured on the paper's design", "measured rate of effect_found on the paper's design"))
    assert added.startswith(f"added: {key}={final:.3g}+-") and "(95%" in added and added.endswith(")")
    assert error.startswith(f"mean Eq. 6 error: {result.waterfall[0]['mean_eq6_error_pct']:.2f}% (start")
    assert left.startswith("trials still unexplained: ")


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["start", "paired"])
def test_a_cheaper_replay_error_finds_the_same_toe_with_fewer_bootstraps(tmp_path, mode):
    """The cheaper ways to the replay's own error than measuring it at every model ("full"): the default "paired",
    and "start" (judged at scale by benchmarks/paper_rates.py --variant): the same toe accepted, its interval
    holding the truth; "start" measures the replay's own error only
    at the start, "paired" in full at the start and the accepted model and by linearize.PAIRED_DRAWS paired draws a
    trial at each polish step."""
    campaign = _campaign(tmp_path, {"wheel_toe_deg": 1.5})
    samples, log = PAIRED_DRAWS + 1, []
    options = dict(candidates=["wheel_toe", "head_drag"], input_noise_samples=samples, max_rounds=1)
    full = _diagnose(campaign, replay_error="full", **options)
    cheap = _diagnose(campaign, replay_error=mode, progress=log.append, **options)
    assert full.accepted == cheap.accepted == ["wheel_toe"]
    value, se = cheap.final_coordinates["wheel_toe_deg"]
    assert abs(value - 1.5) < Z95 * se
    draws = [m for m in log if "the twins replayed with noisy angles" in m]
    n = len(campaign.trials)
    if mode == "start":
        assert draws == [f"the replays' own error: the twins replayed with noisy angles: {n * samples} replays"]
        assert cheap.simulations <= full.simulations - n * (samples + 1)
    else:
        assert [m.endswith(f": {n * samples} replays") and "paired" not in m for m in draws[:2]] == [True, True]
        assert all(m.endswith(f"(paired): {n * PAIRED_DRAWS} replays") for m in draws[2:])


def test_where_no_friction_is_identified_the_search_walks_toward_the_data_unless_an_effect_explains_more(tmp_path):
    """Data made with half the paper's lateral Coulomb friction: the start's replays miss by more than the noise,
    so the paper's own search (one coefficient at a time) runs, and from the paper's values it moves mu_lat toward
    the truth and lowers the diagnosis's sum of squares; a toe cannot do as well, so the searched friction is kept.
    On the same design at the paper's friction it does not run (there it would walk the noise). With a 3 deg toe
    hidden at the paper's friction the start misses too, the search moves mu_lat, but the toe explains more: the
    start's friction is kept for the rounds to find the toe."""
    truth = 0.5 * Friction().mu_lat
    others = [n for n in FRICTION_NAMES if n != "mu_lat"]
    evaluator = Evaluator(None)
    lins = {}
    for label, mu_lat, hidden in (("far", truth, {}), ("at", Friction().mu_lat, {}), ("toe", Friction().mu_lat,
                                  {"wheel_toe_deg": 3.0})):  # fmt: skip
        synthesize_campaign(tmp_path / label, design=[Case([], 1), Case([7], 1)], seed=3, effects=hidden,
                            friction=dataclasses.replace(Friction(), mu_lat=mu_lat),
                            stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.5))  # fmt: skip
        trials = load_campaign(tmp_path / label).trials
        lins[label] = linearize(trials, Friction(), {}, ["wheel_toe"], evaluator, input_noise_samples=2, held=others)
    assert needs_friction_search(lins["far"], ["mu_lat"], [], THRESHOLDS)
    assert not needs_friction_search(lins["at"], ["mu_lat"], [], THRESHOLDS)
    assert needs_friction_search(lins["toe"], ["mu_lat"], [], THRESHOLDS)
    found, note = far_friction(lins["far"], ["mu_lat"], [], ["wheel_toe"], evaluator, THRESHOLDS, 2)
    assert found is not None and truth <= found.mu_lat < Friction().mu_lat, note
    assert dataclasses.replace(found, mu_lat=Friction().mu_lat) == Friction()  # only what was searched moved
    kept, note = far_friction(lins["toe"], ["mu_lat"], [], ["wheel_toe"], evaluator, THRESHOLDS, 2)
    assert note.startswith("searched (mu_lat 1.5 -> "), note  # the friction alone would absorb part of the toe
    assert kept is None and "wheel_toe at the start explains more" in note, note


def test_a_paired_replay_error_at_the_same_model_is_the_full_one(tmp_path):
    """Common random numbers: measured again at the model of the full measurement, the paired draws are its own
    first draws, so the paired bias is the full one exactly; at another model it moves."""
    campaign = _campaign(tmp_path, {}, design=[Case([], 1)], seconds=1.0)
    evaluator = Evaluator(None)
    samples = PAIRED_DRAWS + 1
    full = linearize(campaign.trials, Friction(), {}, [], evaluator, input_noise_samples=samples, held=FRICTION_NAMES)
    again = with_replay_error(full, evaluator, samples, paired=True)
    assert evaluator.simulations == (1 + 1 + samples) + (1 + PAIRED_DRAWS)  # replay, twin, draws; twin, paired draws
    for a, b in zip(full.bias + full.start_bias, again.bias + again.start_bias, strict=True):
        np.testing.assert_array_equal(a, b)
    assert again.noise is full.noise
    other = dataclasses.replace(Friction(), mu_lat=1.0)
    elsewhere = relinearize(full, other, {}, evaluator, samples=samples, paired=True)
    assert np.linalg.norm(elsewhere.bias[0] - full.bias[0]) > 0


# On these short trials a hidden head drag is explained about as well by a tilt or a longitudinal asymmetry,
# and a payload (seed 1) by a tilt (benchmarks/diagnosis.py): no effect may be accepted in the true one's place.
# The payload leaves the residual unexplained (a tilt removes 44% of the held-out error, too little to name it).
# A longitudinal asymmetry at 0.8 on 3 s trials is ranked first (0.9 +- 0.2, 95%) and ties with a 1.3 head drag
# when simulated (87% / 87%): `ambiguous`, both named. (A failed joint's 0.6 N m dry friction ties with a
# longitudinal asymmetry on 2 s trials, 67% / 81% linear; on 3 s trials it is found: test_a_visible_hidden_effect_...)
@pytest.mark.slow
@pytest.mark.parametrize(
    "effect, key, value, seed, seconds, named",
    [
        ("head_drag", "head_drag_mu", 0.5, 0, SECONDS, False),
        ("module_payload", "payload_kg", 0.8, 1, SECONDS, False),
        ("longitudinal_friction_asymmetry", "longitudinal_friction_asymmetry", 0.8, 0, 3.0, True),
    ],
)
def test_look_alikes_get_no_confident_wrong_answer(tmp_path, effect, key, value, seed, seconds, named):
    result = _diagnose(_campaign(tmp_path, {key: value}, seed=seed, seconds=seconds))
    assert all(name == effect for name in result.accepted), (result.verdict, result.rounds[0].table())
    assert result.verdict != "effect_found" or result.accepted == [effect]
    if named:
        assert result.verdict == "ambiguous" and effect in result.rounds[-1].ambiguous, result.explanation


# A servo lag is in the measured angles the replays follow; a lab floor's tilt (4 deg here; the diagnosis
# searches 5 at most) would not be significant on these trials even at 5 deg (a 3-standard-error tilt is
# 6.7 deg downhill x, 20 deg y, measured); a Stribeck breakaway of 1.5 times the Coulomb
# friction moves these trials by less than their noise (only the circling joint-2 failure responds, and
# chaotically: docs/diagnosis.md): its fit is not significant. Its linear detectable strength is not asserted: the
# breakaway acts below a slip speed, and its column at 0 (probe 0.5) differs between machines with the same
# pinned packages (3.3 on one, 0.94 on an AMD EPYC), while the fit finds 0.42 +- 0.62 on both. All three
# hidden in one campaign, to spend one.
@pytest.mark.slow
def test_effects_the_replays_cannot_see_are_reported_not_detectable_and_nothing_else_accepted(tmp_path):
    result = _diagnose(
        _campaign(
            tmp_path,
            {"servo_lag_s": 0.05, "stribeck_ratio": 1.5, "ground_slope_deg": 4.0, "ground_slope_direction_deg": 30.0},
        )
    )
    assert result.accepted == [] and result.verdict == "no_missing_effect", result.rounds[0].table()
    hidden = {d["name"]: d for d in result.not_detectable}
    assert "servo_lag" in hidden and "gait" in hidden["servo_lag"]["experiment"]
    assert "ground_slope" in hidden, result.rounds[0].table()
    stribeck = next(c for c in result.candidates if c.name == "stribeck_friction")
    assert not stribeck.accepted and stribeck.wald_p >= THRESHOLDS.p_accept, (stribeck.status, stribeck.coordinates)
    assert f"stribeck_ratio {stribeck.detectable_strength['stribeck_ratio']:.2g}" in result.explanation


@pytest.mark.slow
@pytest.mark.parametrize("truth_model, start_rates", [("drake", "rest"), ("reference", "fit")])
def test_a_campaign_without_a_hidden_effect_gets_nothing_accepted(tmp_path, truth_model, start_rates):
    """Also when another model made it (reference.py: kinematic joints, the head at rest at its start, not this
    project's convention), with each trial's start fitted beside the physics."""
    result = _diagnose(_campaign(tmp_path, {}, seed=12, truth_model=truth_model), start_rates=start_rates)
    assert result.accepted == [] and result.verdict == "no_missing_effect", result.rounds[0].table()
    assert result.effects == {}
    assert len(result.starts) == (3 * len(result.trials) if start_rates == "fit" else 0)


class FloorSeams(Effect):
    """Outside the library (this test only): floor seams every 0.4 m twist the head about z."""

    name = "floor_seams_test_only"
    summary = "a yaw torque on the head, periodic in its x position"
    parameters = (EffectParameter("floor_seam_torque_Nm", 0.0, 1.0),)

    def configure(self, setup, values):
        torque = values["floor_seam_torque_Nm"]

        def force(x):
            out = np.zeros(16)
            out[2] = torque * math.sin(2 * math.pi * x[0] / 0.4)
            return out

        setup.extra_forces.append(force)


@pytest.mark.slow
def test_an_effect_outside_the_library_gets_no_confident_wrong_answer(tmp_path):
    register(FloorSeams())
    try:
        campaign = _campaign(tmp_path, {"floor_seam_torque_Nm": 0.3})
    finally:
        LIBRARY.pop(FloorSeams.name)
    result = _diagnose(campaign)
    assert result.verdict == "unexplained" or not result.accepted, (result.verdict, result.rounds[0].table())
    assert result.verdict != "effect_found"


@pytest.mark.parametrize(
    "option, value, named",
    [
        ("--design", "none,J7y", "'J7y'"),
        ("--design", "noneb4.4.4", "'noneb4.4.4'"),
        ("--effects", "wheel_toe,gravity", "'gravity'"),
        ("--strengths", "1,two", "'1,two'"),
        ("--strengths", "1,2", "joint_coulomb_Nm at 1.2,"),
    ],
)
def test_the_benchmark_names_a_bad_option_in_one_line_before_any_campaign(tmp_path, option, value, named):
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "diagnosis.py"),
            option,
            value,
            "--out",
            str(tmp_path / "rows.jsonl"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode != 0 and not (tmp_path / "rows.jsonl").exists()
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(option) and named in lines[0], proc.stderr


@pytest.mark.parametrize("option, value", [("--seeds", "10x"), ("--cells", "none,gravity")])
def test_the_paper_rates_benchmark_names_a_bad_option_in_one_line_before_any_campaign(tmp_path, option, value):
    proc = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "paper_rates.py"), option, value, "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode != 0 and not (tmp_path / "out").exists()
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(option) and repr(value.split(",")[-1]) in lines[0], proc.stderr


def test_an_interrupted_diagnosis_resumes_from_its_checkpoint_with_the_same_answer(tmp_path):
    campaign = _campaign(tmp_path / "c", {"wheel_toe_deg": 1.5}, design=[Case([], 1), Case([7], 1)])
    options = dict(candidates=["wheel_toe", "head_drag"], input_noise_samples=2, max_rounds=1)
    whole = _diagnose(campaign, **options)
    batches = []

    def interrupt_at_the_fourth_batch(text):
        batches.append(text)
        if len(batches) == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _diagnose(campaign, progress=interrupt_at_the_fourth_batch, checkpoint=tmp_path / "checkpoint", **options)
    again = _diagnose(campaign, checkpoint=tmp_path / "checkpoint", **options)
    assert 0 < again.resumed < again.simulations == whole.simulations  # three batches came from the checkpoint
    assert (again.verdict, again.effects, again.friction) == (whole.verdict, whole.effects, whole.friction)
    assert [c.coordinates for c in again.candidates] == [c.coordinates for c in whole.candidates]


def test_no_checkpointed_job_imports_a_decision_only_module():
    """The checkpoints' code version leaves the decision-only modules out (sysid.evaluate.DECISION_ONLY), so a rule
    changed there reuses the replays on disk: that is right only if no job function's module needs them, directly or
    through the modules it imports (package __init__ files aside: a job calls functions, not the package)."""
    import ast

    from rc1_drake.sysid.evaluate import DECISION_ONLY

    root = REPO / "rc1_drake"
    jobs = [
        "diagnose/replays.py",
        "diagnose/discover.py",
        "sysid/input_noise.py",
        "sysid/residual.py",
        "identify/avs.py",
    ]

    def imported(relative: str) -> set:
        here = (root / relative).parent
        found = set()
        for node in ast.walk(ast.parse((root / relative).read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = here
                for _ in range(node.level - 1):
                    base = base.parent
                target = base.joinpath(*node.module.split(".")) if node.module else base
                for name in [target.with_suffix(".py"), *(target / f"{a.name}.py" for a in node.names)]:
                    if name.is_file():
                        found.add(name.relative_to(root).as_posix())
        return found

    seen, todo = set(), list(jobs)
    while todo:
        module = todo.pop()
        if module not in seen:
            seen.add(module)
            todo += sorted(imported(module) - seen)
    assert {"diagnose/linearize.py", "sysid/evaluate.py", "replay.py"} <= seen  # the walk follows imports
    assert not seen & set(DECISION_ONLY), sorted(seen & set(DECISION_ONLY))


def test_the_paper_rates_table_counts_a_seed_only_once_every_cell_is_diagnosed(monkeypatch):
    """A seed part-way through the grid would weigh the cells it reached: its rows wait, and the table names it."""
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    paper_rates = importlib.import_module("paper_rates")
    grid, shown = paper_rates.CELLS, paper_rates.CELLS[:2]
    whole = [{"cell": c.label, "seed": 102} for c in grid]
    begun = [{"cell": c.label, "seed": 103} for c in grid[:2]] + [{"cell": "a cell of no grid", "seed": 103}]
    counted, note = paper_rates.complete_seeds(whole + begun, shown)
    assert counted == whole[:2]  # the shown cells of the complete seed: a seed with every shown cell still waits
    assert note == f"Not yet counted, in progress: seed 103 (2 of {len(grid)} cells)."
    assert paper_rates.complete_seeds(whole, grid) == (whole, "")


def test_the_paper_rates_minutes_are_a_whole_run_of_the_campaign_under_any_variant(monkeypatch):
    """A variant replays only where it parts from another's checkpoint: its minutes are that whole run's, its own
    whole run's where it has one, and never a run resumed, paused, timed beside other work or on an older engine, nor
    one that made more replays than the default did."""
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    paper_rates = importlib.import_module("paper_rates")

    def row(seed, variant, wall_s, simulations=500, **flags):
        return {"cell": "none", "seed": seed, "variant": variant, "wall_s": wall_s, "simulations": simulations, **flags}

    rows = [
        row(102, "other", 300.0),
        row(102, "default", 20.0, resumed=500),
        row(103, "other", 250.0),
        row(103, "default", 200.0),
        row(104, "other", 900.0, shared_cpu=True),
        row(104, "default", 30.0, resumed=400),
        row(105, "default", 99.0, paused=True),
        row(105, "other", 400.0, older_engine=True),
        row(106, "default", 50.0, resumed=500),
        row(106, "other", 600.0, simulations=650),  # more replays than the default's: not what the default costs
    ]
    assert paper_rates.whole_runs(rows) == {("none", 102): 300.0, ("none", 103): 200.0}
    defaults = [{**r, "outcome": "right", "coverage": [], "accepted": []} for r in rows if r["variant"] == "default"]
    body, _ = paper_rates.table(defaults, paper_rates.CELLS, paper_rates.whole_runs(rows))
    assert body.splitlines()[2].endswith(f"| {(300.0 + 200.0) / 2 / 60:.1f} |")  # the median of 102's and 103's
    assert paper_rates.table(defaults, paper_rates.CELLS)[0].splitlines()[2].endswith(f"| {200.0 / 60:.1f} |")


def test_the_paper_rates_page_says_how_often_each_verdict_held_on_the_campaigns_it_counts(monkeypatch):
    """The verdicts' line under each table is counted from its rows (a verdict holds as diagnose.verdict says)."""
    monkeypatch.syspath_prepend(str(REPO / "benchmarks"))
    paper_rates = importlib.import_module("paper_rates")
    null, toe = paper_rates.CELLS[0].label, next(c.label for c in paper_rates.CELLS if c.expected == ("wheel_toe",))
    rows = [
        {"cell": null, "verdict": "no_missing_effect", "outcome": "right"},
        {"cell": toe, "verdict": "no_missing_effect", "outcome": "missed"},
        {"cell": toe, "verdict": "effect_found", "outcome": "right"},
        {"cell": null, "verdict": "effect_found", "outcome": "wrong"},
    ]
    line = paper_rates.verdicts_read(rows)
    assert "`effect_found` held (the hidden effects exactly) on 1 of 2" in line
    assert "`no_missing_effect` held (nothing hidden) on 1 of 2" in line
    assert "`ambiguous` held (something hidden) on 0 of 0" in line


def test_the_probe_kind_that_tells_two_candidates_apart_sees_what_neither_mimics():
    """probe.telling_apart on hand-made columns: a kind where the two are parallel never tells them apart; of the
    others, the one where the part each cannot mimic is seen soonest, relative to where each is seen at all."""
    from rc1_drake.diagnose.probe import apart_strengths, telling_apart

    a, b = np.array([[3.0], [4.0]]), np.array([[1.0], [0.0]])
    assert apart_strengths(a, b) == pytest.approx([3.0 / 4.0])  # a's part orthogonal to b: (0, 4)
    assert apart_strengths(b, 2 * b) == [math.inf]

    def kind(cols_a, cols_b):
        cols_a, cols_b = np.array(cols_a, float), np.array(cols_b, float)
        return {
            n: {"columns": c, "detectable_strength": {f"{n}_x": 3.0 / float(np.linalg.norm(c))}}
            for n, c in (("a", cols_a), ("b", cols_b))
        }

    study = {
        "parallel, seen best": kind([[30.0], [0.0]], [[60.0], [0.0]]),
        "apart, seen weakly": kind([[0.0], [0.1]], [[0.1], [0.0]]),
        "apart, seen well": kind([[3.0], [3.0]], [[3.0], [0.0]]),
    }
    chosen, strengths = telling_apart(study, "a", "b")
    assert chosen == "apart, seen well"
    assert strengths == pytest.approx({"a_x": 1.0, "b_x": 3.0 / (3.0 / math.sqrt(2))})


def test_an_ambiguous_verdict_is_one_sentence_with_the_trial_for_each_pair_once_under_it():
    """Three candidates tied: each carries the trials that tell it from the other two (probe.suggest_experiments), so
    each pair's trial is on two candidates; the verdict is one sentence, and the pairs under it (open_pairs) each
    once, none with a candidate outside the tie."""
    from types import SimpleNamespace

    texts = {("a", "b"): "X tells a and b apart", ("a", "c"): "Y tells a and c apart", ("b", "c"): "Z tells b and c"}
    texts[("a", "d")] = "W tells a and d apart"
    candidates = []
    for name in "abc":
        apart = {(set(p) - {name}).pop(): t for p, t in texts.items() if name in p}
        candidates.append(SimpleNamespace(name=name, apart=apart, simulated={"held_out_reduction": 0.5}))
    rounds = [SimpleNamespace(ambiguous=["a", "b", "c"], candidates=candidates)]
    kind, sentence = verdicts.verdict([], None, rounds)
    assert kind == "ambiguous" and sentence.endswith(
        "these trials cannot tell them apart; the trials that would are below"
    )
    pairs = verdicts.open_pairs(rounds)
    assert sorted(pairs) == [
        ("a", "b", texts[("a", "b")]),
        ("a", "c", texts[("a", "c")]),
        ("b", "c", texts[("b", "c")]),
    ]


def test_a_friction_search_that_fits_the_trials_without_a_failed_joint_worse_is_not_kept():
    """worse_without_failures: the searched friction moves the no-failure trials' residuals up by 3 (12 rows each,
    -2 log likelihood 0 -> 2 x 108) and the failed-joint trials' down: not kept, whatever the failed trials gained.
    Where the no-failure trials fit it better, or no trial is free of a failed joint, it does not judge; a rise within
    2 per moved coordinate (AIC) is let through."""
    zero = {"a": [np.zeros(12)] * 4, "b": [np.zeros(12)] * 4}
    start = _linearization(zero, [np.zeros(12), np.full(12, 5.0)] * 2)
    worse = _linearization(zero, [np.full(12, 3.0), np.zeros(12)] * 2)
    before, after = worse_without_failures(start, worse, [], 2)
    assert (before, after) == pytest.approx((0.0, 2 * 12 * 9.0))
    assert worse_without_failures(worse, start, [], 2) is None
    slightly = _linearization(zero, [np.full(12, 0.2), np.zeros(12)] * 2)  # 2 x 12 x 0.04 = 0.96 < 2 x 1
    assert worse_without_failures(start, slightly, [], 1) is None
    assert worse_without_failures(start, slightly, [], 0) is not None
    for lin in (start, worse):  # every trial with a failed joint
        lin.trials = [dataclasses.replace(t, failed_joints=[7]) for t in lin.trials]
    assert worse_without_failures(start, worse, [], 2) is None


def test_the_failed_joints_law_is_a_nuisance_only_where_a_joint_failed_and_never_twice():
    none, j7 = (dataclasses.replace(_FAKE_TRIAL, failed_joints=f) for f in ([], [7]))
    assert failed_joint_law_effects([none, j7], {}) == list(FAILED_JOINT_LAW)
    assert failed_joint_law_effects([none], {}) == []
    assert failed_joint_law_effects([j7], {"joint_coulomb_Nm": 0.2}) == ["compliant_stop"]


@pytest.mark.slow
def test_a_failed_joints_dry_torque_fitted_as_nuisance_is_no_missing_effect_and_its_interval_holds(tmp_path):
    """A 0.3 N m dry torque in the failed joint, the candidates without it: with the failed joints' law fitted in
    every fit (failed_joint_law), nothing is missing, and the fitted torque's 95% interval holds the truth."""
    campaign = _campaign(tmp_path, {"joint_coulomb_Nm": 0.3}, seed=12)
    result = _diagnose(campaign, candidates=["wheel_toe", "head_drag"], failed_joint_law=True)
    assert result.accepted == [] and result.verdict == "no_missing_effect", result.rounds[0].table()
    assert {c.name for r in result.rounds for c in r.candidates} <= {"wheel_toe", "head_drag"}
    value, se = result.final_coordinates["joint_coulomb_Nm"]
    assert abs(value - 0.3) <= Z95 * se, (value, se)


def test_a_held_coefficient_known_to_a_factor_widens_an_effect_by_the_shift_its_error_makes():
    """A held coordinate a (at 0.5) correlated with the effect's b: where the truth's a is 20% off, b's fit moves by
    0.2 times the square root of the variance considered_variance carries per unit of log-error, exactly (linear); with
    a uncorrelated with b, nothing is carried."""
    rng = np.random.default_rng(4)
    a, noise = rng.normal(size=(4, 12)), rng.normal(size=(4, 12))
    b = 0.6 * a + 0.8 * noise
    lin = _linearization({"a": list(a), "b": list(b)}, list(-(0.2 * 0.5) * a))  # the truth: a 20% above 0.5, b 0
    lin.coordinates[0] = dataclasses.replace(lin.coordinates[0], value=0.5)
    carried = considered_variance(lin, ["b"], ["a"])
    assert abs(fit(lin, ["b"]).values[0]) == pytest.approx(0.2 * math.sqrt(carried[0]), rel=1e-6)
    apart = _linearization({"a": list(a), "b": list(noise - a * (a * noise).sum() / (a * a).sum())}, list(0 * a))
    apart.coordinates[0] = dataclasses.replace(apart.coordinates[0], value=0.5)
    assert considered_variance(apart, ["b"], ["a"])[0] == pytest.approx(0.0, abs=1e-20)


def test_friction_at_a_bound_of_its_range_is_reported_without_an_interval():
    """A free coefficient the fit ran to a bound of (the loop's at_bound: a failed joint's law mis-modelled pushes
    c_joint to 0.5 on another lab's data) is named with its value and no interval, in the summary and the JSON."""
    from rc1_drake.diagnose.report import Diagnosis
    from rc1_drake.diagnose.verdict import Verdict

    result = Diagnosis(
        campaign="c", start_friction=Friction(), start_effects={}, free=["c_joint", "mu_lat"], rounds=[], waterfall=[],
        friction=Friction(c_joint=0.5, mu_lat=1.2), effects={}, accepted=[], verdict=Verdict.AMBIGUOUS,
        explanation="x", misfit_p=0.1, not_detectable=[], where_it_fails=None, simulations=0, wall_s=0.0,
        final_coordinates={"c_joint": [0.5, 0.1], "mu_lat": [1.2, 0.1]}, at_bound=["c_joint"],
    )  # fmt: skip
    lines = result.summary()
    assert lines[lines.index("added: nothing") + 1] == (
        "friction at a bound of its range, no interval (no measurement: the model's form cannot follow the data "
        "there): c_joint=0.5"
    )
    assert result.to_json()["at_bound"] == ["c_joint"]
    assert not any("friction at a bound" in line for line in dataclasses.replace(result, at_bound=[]).summary())


def test_the_reported_interval_takes_the_jackknife_over_cases_where_twins_share_an_error():
    """Two trials of each of four cases share an error of the model's form (as another lab's linkage moves every
    trial of a case alike): leaving one trial out keeps its twin's, so the fit's own interval (sandwich and trial
    jackknife) misses the truth often; the case jackknife (each case left out, by hand: least squares of the rest)
    sees it, and the reported interval (its variance widened to Student's t at 3 degrees of freedom) holds. Measured
    over 200 draws: 69% of the fit's 95% intervals hold, 92.5% of the reported ones."""
    from rc1_drake.diagnose.fit import case_jackknife, reported_standard_errors

    rng = np.random.default_rng(11)
    kinds = [([], 0.0), ([7], 0.0), ([13], 0.0), ([7], -0.9)] * 2
    trials = [
        dataclasses.replace(_FAKE_TRIAL, trial_id=f"t{k}", failed_joints=j, gait=Gait(bias_deg=bias))
        for k, (j, bias) in enumerate(kinds)
    ]
    held = {"fit": 0, "reported": 0}
    for draw in range(200):
        x = [rng.normal(1.0, 0.3, 12) for _ in trials]
        shared = rng.normal(0.0, 0.3, 4)  # the case's error, in units of the coordinate
        r0 = [-(0.5 + shared[k % 4]) * x[k] + 0.1 * rng.normal(size=12) for k in range(len(trials))]
        lin = dataclasses.replace(
            _linearization({"a": [0 * v for v in x], "b": x}, r0, trials=len(trials)), trials=trials
        )
        fitted = fit(lin, ["b"])
        reported = reported_standard_errors(lin, fitted)
        if draw == 0:  # by hand: the case jackknife of the least-squares steps without each case
            steps = [np.linalg.lstsq(np.concatenate([x[k] for k in range(8) if k % 4 != g])[:, None],
                                     -np.concatenate([r0[k] for k in range(8) if k % 4 != g]), rcond=None)[0][0]
                     for g in range(4)]  # fmt: skip
            assert case_jackknife(lin, ["b"])[0, 0] == pytest.approx(0.75 * np.sum((steps - np.mean(steps)) ** 2))
            assert reported[0] >= fitted.standard_errors[0]
        held["fit"] += abs(fitted.values[0] - 0.5) <= Z95 * fitted.standard_errors[0]
        held["reported"] += abs(fitted.values[0] - 0.5) <= Z95 * reported[0]
    assert held["fit"] < 0.75 * 200 and held["reported"] > 0.88 * 200, held
