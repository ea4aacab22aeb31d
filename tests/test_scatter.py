"""The failed joint's scatter as a variance component (diagnose/scatter.py): its scale by maximum likelihood, its
bound, the misfit that takes it as noise, and its columns against the linearization's."""

import dataclasses

import numpy as np

from rc1_drake.config import FRICTION_NAMES, Friction, Stop
from rc1_drake.diagnose.linearize import Linearization, linearize
from rc1_drake.diagnose.scatter import TERMS, Scatter, failed_joint_scatter
from rc1_drake.diagnose.significance import misfit
from rc1_drake.diagnose.thresholds import Thresholds
from rc1_drake.gait import Gait
from rc1_drake.measurements import Trial, load_campaign
from rc1_drake.synthesize import Case, synthesize_campaign
from rc1_drake.sysid.evaluate import Evaluator

NOISE = 1.5  # each trial's final-position variance per axis (hand and input noise, standardized)


def _draws(rng, trials: int, tau: float, shared=None) -> tuple:
    """(Scatter, residuals): every other trial has a failed joint whose final position moves by X b, b ~ N(0, tau^2 I)
    drawn per trial (or `shared`, the same b for every trial: a law, not a scatter), on top of the noise."""
    columns = [rng.normal(size=(2, 3)) if k % 2 else None for k in range(trials)]
    residual = []
    for x in columns:
        r = np.sqrt(NOISE) * rng.normal(size=2)
        if x is not None:
            r = r + x @ (tau * rng.normal(size=3) if shared is None else shared)
        residual.append(np.concatenate([r, rng.normal(size=4)]))  # path rows: not the scatter's
    return Scatter(columns), residual


def test_the_scatters_scale_is_its_maximum_likelihood_and_none_is_taken_beyond_its_bound():
    rng = np.random.default_rng(0)
    estimates = [Scatter.scale(*_draws(rng, 400, 2.0), [NOISE] * 400, bound=100.0)[0] for _ in range(5)]
    assert abs(np.mean(estimates) - 2.0) < 0.15  # 200 failed-joint trials: about 4% of tau each
    scatter, residual = _draws(rng, 400, 2.0)
    assert scatter.scale(residual, [NOISE] * 400, bound=1.0) == (0.0, scatter.scale(residual, [NOISE] * 400, 100.0)[0])
    nulls = [Scatter.scale(*_draws(rng, 40, 0.0), [NOISE] * 40, bound=100.0)[0] for _ in range(20)]
    assert np.median(nulls) < 0.3  # no scatter: mostly none found
    assert scatter.scale(residual, [NOISE] * 400, bound=0.0) == (0.0, 0.0)  # off: nothing estimated


def _lin(trials: int) -> Linearization:
    fake = Trial(trial_id="t", failed_joints=[], gait=Gait(), stop=None, initial_head_pose=np.zeros(3),
                 final_head_xy=np.ones(2), t=np.zeros(2), q=np.zeros((2, 13)), head_yaw_rate=np.zeros(2))  # fmt: skip
    fakes = [dataclasses.replace(fake, trial_id=f"t{k}", failed_joints=[7] if k % 2 else []) for k in range(trials)]
    return Linearization(fakes, Friction(), {}, [], [np.zeros(6)] * trials, [0.0] * trials, [0.0] * trials, {},
                         [np.eye(6) * (NOISE - 1.0)] * trials)  # fmt: skip


def test_a_misfit_takes_the_failed_joints_scatter_as_noise_up_to_its_bound_and_still_sees_the_other_trials():
    rng = np.random.default_rng(1)
    scatter, residual = _draws(rng, 40, 3.0)
    lin = _lin(40)
    taken = Thresholds(max_failed_joint_scatter=10.0)
    assert not misfit(lin, residual, 0).consistent  # the noise alone: the failed-joint trials are far off
    left = misfit(lin, residual, 0, taken, scatter)
    assert left.consistent and 2.0 < left.scatter < 4.5 and not left.outliers
    beyond = misfit(lin, residual, 0, Thresholds(max_failed_joint_scatter=0.5), scatter)
    assert not beyond.consistent and beyond.scatter == 0 and beyond.scatter_unbounded == left.scatter
    residual[0] = residual[0] + np.array([8.0, 0.0, 0, 0, 0, 0])  # a no-failure trial 8 sigmas off: not scatter
    assert list(misfit(lin, residual, 0, taken, scatter).outliers) == ["t0"]
    # A law the failed joint follows in every trial alike (the same terms) is a scatter too, once large enough:
    # only the bound keeps it a finding (diagnose/scatter.py).
    _, law = _draws(rng, 40, 0.0, shared=np.array([6.0, 0.0, 0.0]))
    assert misfit(lin, law, 0, Thresholds(max_failed_joint_scatter=100.0), scatter).scatter > 3.0
    assert not misfit(lin, law, 0, Thresholds(max_failed_joint_scatter=1.0), scatter).consistent


def test_the_scatters_columns_are_the_linearizations_columns_of_the_failed_joints_terms(tmp_path):
    synthesize_campaign(tmp_path, design=[Case([], 1), Case([7], 1)], seed=2,
                        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.0))  # fmt: skip
    trials = load_campaign(tmp_path).trials
    evaluator = Evaluator(None)
    lin = linearize(trials, Friction(), {}, list(TERMS), evaluator, input_noise_samples=2, held=FRICTION_NAMES)
    before = evaluator.simulations
    scatter = failed_joint_scatter(lin, evaluator)
    assert evaluator.simulations - before == len(TERMS)  # one replay a term, of the one failed-joint trial
    failed = [k for k, t in enumerate(lin.trials) if t.failed_joints]
    assert [x is not None for x in scatter.columns] == [bool(t.failed_joints) for t in lin.trials]
    for j, name in enumerate(TERMS):
        c = next(c for c in lin.coordinates if c.owner == name)
        for k in failed:
            expected = c.step * lin.columns[c.name][k]
            np.testing.assert_allclose(scatter.columns[k][:, j], expected, rtol=1e-9, atol=1e-12)
            assert np.linalg.norm(expected[:2]) > 1e-3  # the failed joint's terms move its final position
    weighed = scatter.weighing(lin, 2.0)
    assert all(weighed.weights[k] < lin.weights[k] for k in failed)  # its scatter is noise: it weighs less
    assert all(weighed.weights[k] == lin.weights[k] for k in range(len(trials)) if k not in failed)
    np.testing.assert_array_equal(scatter.weighing(lin, 0.0).weights, lin.weights)
