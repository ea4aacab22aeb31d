"""An independent implementation of the planar equations of motion (paper Eq. 1, rc1_drake.reference:
real-vector kinematics, Lagrange's equations, SciPy's LSODA) agrees with the Drake Diagram.

As in the paper, the reference prescribes the working joints; it is given the angles that Drake's
servos achieved, so that the comparison checks the multibody dynamics, the wheel friction and the
failed joint, not the servo model. The smoothing is coarser than the default (5 mm/s, for both) only
to keep the stiff reference integration short.
"""


import numpy as np
import pytest

from rc1_drake.config import Failure, Numerics, Scenario
from rc1_drake.reference import simulate_reference

CASES = {"nominal": [], "joint_7": [Failure(joint=7)]}


@pytest.mark.parametrize("case", CASES)
def test_reference_model_agrees_with_drake(simulate_cached, case):
    scenario = Scenario(failures=CASES[case], numerics=Numerics(sgn_smoothing_m_s=5e-3, log_period_s=0.005))
    run = simulate_cached(scenario)
    ref = simulate_reference(scenario, run.geometry, joint_path=(run.t, run.q), rtol=1e-5, atol=1e-7)
    assert ref.crossed and run.stop_reason == "crossed"
    travelled = np.linalg.norm(run.head_xy[-1] - run.head_xy[0])
    assert np.linalg.norm(ref.head_xy[-1] - run.head_xy[-1]) < 0.02 * travelled
    assert abs(ref.t[-1] - run.t[-1]) < 0.02 * run.t[-1]
    # Along the way too: the head paths at common times.
    ys = np.interp(run.t, ref.t, ref.head_xy[:, 1])
    assert np.abs(ys - run.head_xy[:, 1]).max() < 0.02 * travelled
