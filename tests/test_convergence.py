"""Numerical convergence: halving the time step or the sgn() smoothing moves the final head position
by less than 1% of the distance travelled, for the nominal run and the (more sensitive) joint-7 failure."""

import dataclasses

import numpy as np
import pytest

from rc1_drake.config import Failure, Scenario

CASES = {"nominal": [], "joint_7": [Failure(joint=7)]}


def _moved(a, b):
    travelled = np.linalg.norm(a.head_xy[-1] - a.head_xy[0])
    return np.linalg.norm(a.head_xy[-1] - b.head_xy[-1]) / travelled


@pytest.mark.parametrize("case", CASES)
def test_halving_the_time_step(simulate_cached, case):
    scenario = Scenario(failures=CASES[case])
    n = scenario.numerics
    finer = dataclasses.replace(scenario, numerics=dataclasses.replace(n, time_step_s=n.time_step_s / 2))
    assert _moved(simulate_cached(scenario), simulate_cached(finer)) < 0.01


@pytest.mark.parametrize("case", CASES)
def test_halving_the_sign_smoothing(simulate_cached, case):
    scenario = Scenario(failures=CASES[case])
    n = scenario.numerics
    sharper = dataclasses.replace(scenario, numerics=dataclasses.replace(n, sgn_smoothing_m_s=n.sgn_smoothing_m_s / 2))
    assert _moved(simulate_cached(scenario), simulate_cached(sharper)) < 0.01
