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
@pytest.mark.parametrize("field", ["time_step_s", "sgn_smoothing_m_s"])
def test_halving_the_step_or_the_sign_smoothing(simulate_cached, case, field):
    scenario = Scenario(failures=CASES[case])
    n = scenario.numerics
    finer = dataclasses.replace(scenario, numerics=dataclasses.replace(n, **{field: getattr(n, field) / 2}))
    assert _moved(simulate_cached(scenario), simulate_cached(finer)) < 0.01
