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


def test_a_campaign_made_by_the_reference_model_records_its_own_start(tmp_path):
    """`synthesize --truth-model reference`: the planar model's trial, recorded 0.5 s after the robot started
    from the head at rest, at 50 Hz: the recorded gait's wave is advanced by those 0.5 s (the measured angles
    are its serpenoid), the data begin in motion, and effects it cannot express are refused."""
    import dataclasses

    from rc1_drake.config import Rc1Error, Stop
    from rc1_drake.gait import serpenoid
    from rc1_drake.measurements import load_campaign
    from rc1_drake.synthesize import Case, Noise, synthesize_campaign

    silent = dataclasses.replace(Noise().scaled(0.0), camera_dropout=0.0)
    synthesize_campaign(
        tmp_path / "c",
        design=[Case([], 1)],
        truth_model="reference",
        record_after_s=0.5,
        sample_period_s=0.02,
        stop=Stop(time_limit_s=1.0),
        noise=silent,
        seed=3,
    )
    trial = load_campaign(tmp_path / "c").trials[0]
    np.testing.assert_allclose(np.diff(trial.t), 0.02, atol=1e-9)
    assert trial.t[-1] == pytest.approx(1.0)
    commanded = np.array([serpenoid(t, trial.gait)[0] for t in trial.t - trial.t[0]])
    np.testing.assert_allclose(trial.q, commanded, atol=1e-6)
    start_speed = np.linalg.norm(trial.camera[1, :2] - trial.camera[0, :2]) / 0.02
    assert start_speed > 0.05  # m/s: the head was moving when the recording began
    with pytest.raises(Rc1Error, match="can express wheel_toe_deg and the sensor faults .* only, not head_drag_mu"):
        synthesize_campaign(
            tmp_path / "d", design=[Case([], 1)], truth_model="reference", effects={"head_drag_mu": 0.2}
        )
    with pytest.raises(Rc1Error, match="non-negative multiple of the sample period, got 0.015"):
        synthesize_campaign(
            tmp_path / "e", design=[Case([], 1)], truth_model="reference", record_after_s=0.015, sample_period_s=0.01
        )
    with pytest.raises(Rc1Error, match="truth model must be one of drake, reference, got 'mujoco'"):
        synthesize_campaign(tmp_path / "f", design=[Case([], 1)], truth_model="mujoco")
