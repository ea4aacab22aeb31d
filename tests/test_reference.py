"""An independent implementation of the planar equations of motion (paper Eq. 1, rc1_drake.reference:
real-vector kinematics, Lagrange's equations, SciPy's LSODA) agrees with the Drake Diagram.

As in the paper, the reference prescribes the working joints; it is given the angles that Drake's
servos achieved, so that the comparison checks the multibody dynamics, the wheel friction and the
failed joint, not the servo model. The smoothing is coarser than the default (5 mm/s, for both) only
to keep the stiff reference integration short.
"""

import dataclasses
import math

import numpy as np
import pytest

from rc1_drake.config import Failure, Numerics, Scenario, Stop
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
    from rc1_drake.config import Rc1Error
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
    with pytest.raises(Rc1Error, match="can express wheel_toe_deg, tail_tether_N, .* only, not head_drag_mu"):
        synthesize_campaign(
            tmp_path / "d", design=[Case([], 1)], truth_model="reference", effects={"head_drag_mu": 0.2}
        )
    with pytest.raises(Rc1Error, match="floor_seam_Nm: only the reference truth model reads these"):
        synthesize_campaign(tmp_path / "g", design=[Case([], 1)], effects={"floor_seam_Nm": 1.0})
    with pytest.raises(Rc1Error, match="non-negative multiple of the sample period, got 0.015"):
        synthesize_campaign(
            tmp_path / "e", design=[Case([], 1)], truth_model="reference", record_after_s=0.015, sample_period_s=0.01
        )
    with pytest.raises(Rc1Error, match="truth model must be one of drake, reference, got 'mujoco'"):
        synthesize_campaign(tmp_path / "f", design=[Case([], 1)], truth_model="mujoco")


HIDDEN = {  # forces outside the paper's model, strong enough to turn the head's path by a visible angle
    "nominal": ([], {"discrepancy_head_push_lat_N": 1.0, "discrepancy_head_side_by_long_N_s_per_m": 2.0,
                     "tail_tether_N": 2.0, "discrepancy_rear_drag_lat_N_s_per_m": -1.5,
                     "discrepancy_middle_dry_long_N": 0.3}),
    "joint_7": ([Failure(joint=7)], {"discrepancy_failed_joint_bias_Nm": 0.1, "discrepancy_failed_joint_dry_Nm": 0.05,
                                     "discrepancy_failed_joint_spring_Nm_per_rad": 0.2,
                                     "discrepancy_tail_drag_long_N_s_per_m": 2.0}),
}  # fmt: skip


@pytest.mark.parametrize("case", HIDDEN)
def test_the_reference_model_applies_the_discrepancy_terms_and_the_tether_as_drake_does(simulate_cached, case):
    """Written anew from their definitions (reference.HiddenForces), the tether and the discrepancy terms move the
    reference's head as the Drake Diagram's (friction.py's kernels) move it: given Drake's achieved angles, the
    heading agrees several times closer with them than without them (measured: 0.03 against 0.31 deg nominal,
    0.48 against 2.9 deg with joint 7 free, over 4 s)."""
    failures, effects = HIDDEN[case]
    scenario = Scenario(failures=failures, numerics=Numerics(sgn_smoothing_m_s=5e-3, log_period_s=0.005),
                        effects=effects, stop=Stop(time_limit_s=4.0))  # fmt: skip
    run = simulate_cached(scenario)
    errors = {}
    for label, effects_there in (("with", effects), ("without", {})):
        there = dataclasses.replace(scenario, effects=effects_there)
        ref = simulate_reference(there, run.geometry, joint_path=(run.t, run.q), rtol=1e-5, atol=1e-7)
        errors[label] = np.abs(np.interp(run.t, ref.t, ref.head_yaw) - run.head_yaw).max()
    assert errors["with"] < errors["without"] / 4
    assert errors["with"] < np.radians(1.0)


def test_hidden_forces_read_their_keys_and_act_as_defined():
    """Hand values of the site law (module frame: +long toward the head, +lat to its left; a positive drag or dry
    coefficient resists), of a failed joint's torque and of a floor seam's; an unknown term is refused by name."""
    from rc1_drake.reference import SEAM_WIDTH_M, HiddenForces, site_law

    eps = 1e-3
    assert site_law({"side_by_long": 3.0}, 0.2, 0.0, eps) == pytest.approx((0.0, 0.6))
    assert site_law({"drag_lat": 2.0, "push_long": 0.5}, 0.1, -0.05, eps) == pytest.approx((0.5, 0.1))
    assert site_law({"quad_long": 2.0, "quad_lat": 1.0}, -0.3, 0.2, eps) == pytest.approx((0.18, -0.04))
    f_long, f_lat = site_law({"dry_long": 1.0, "dry_lat": 1.0}, 1.0, -1.0, eps)
    assert f_long == pytest.approx(-1.0, rel=1e-6) and f_lat == pytest.approx(1.0, rel=1e-6)
    hidden = HiddenForces.from_effects(
        {"tail_tether_N": 1.5, "wheel_toe_deg": 2.0, "discrepancy_failed_joint_spring_Nm_per_rad": 0.3,
         "discrepancy_failed_joint_bias_Nm": 0.1, "discrepancy_head_side_by_long_N_s_per_m": 3.0}
    )  # fmt: skip
    assert hidden.tether_N == 1.5 and hidden.sites == {"head": {"side_by_long": 3.0}}
    assert hidden.joint_torque(np.array([0.5]), np.array([0.0])) == pytest.approx([0.1 - 0.3 * 0.5])
    assert not HiddenForces.from_effects({"wheel_toe_deg": 1.0})
    seam = HiddenForces.from_effects({"floor_seam_Nm": 2.0, "floor_seam_x_m": 1.0})
    assert seam.seam_torque(1.0) == 2.0 and seam.seam_torque(1.0 + SEAM_WIDTH_M) == pytest.approx(2.0 * np.exp(-0.5))
    with pytest.raises(ValueError, match="unknown discrepancy term 'discrepancy_head_spin_N'"):
        HiddenForces.from_effects({"discrepancy_head_spin_N": 1.0})


def test_the_reference_failed_joint_stop_is_a_pd_beyond_the_limit_of_its_truth_gain():
    """Another form of failed joint (issue 67): hand values of the stop's torque (zero inside +-38 deg; past it,
    -k (|q| - 38 deg) sgn(q) - d q_dot), and a softer stop lets a free joint 7 swing farther past the limit."""
    from rc1_drake.config import Rc1Error
    from rc1_drake.engine.dynamics import plant_numbers
    from rc1_drake.reference import LIMIT_RAD, HiddenForces
    from rc1_drake.synthesize import Case, synthesize_campaign

    soft = HiddenForces.from_effects({"reference_stop_Nm_per_rad": 20.0, "reference_stop_Nm_s_per_rad": 0.5})
    q, qd = np.array([0.1, LIMIT_RAD + 0.05, -LIMIT_RAD - 0.1]), np.array([1.0, 0.2, -0.4])
    np.testing.assert_allclose(soft.stop_torque(q, qd), [0.0, -20.0 * 0.05 - 0.5 * 0.2, 20.0 * 0.1 + 0.5 * 0.4])
    assert HiddenForces.from_effects({}).stop_gain == 200.0
    with pytest.raises(ValueError, match="stop needs a gain > 0"):
        HiddenForces.from_effects({"reference_stop_Nm_per_rad": 0.0})
    with pytest.raises(Rc1Error, match="reference_stop_Nm_per_rad: only the reference truth model"):
        synthesize_campaign(None, design=[Case([7], 1)], effects={"reference_stop_Nm_per_rad": 20.0})
    with pytest.raises(
        Rc1Error, match=r"^synthesize: reference: the failed joint's stop needs a gain > 0 .* got 20.0 N m/rad and -1.0"
    ):
        synthesize_campaign(
            None, design=[Case([7], 1)], truth_model="reference", effects={"reference_stop_Nm_s_per_rad": -1.0,
                                                                           "reference_stop_Nm_per_rad": 20.0}
        )  # fmt: skip
    reach = {}
    for gain in (20.0, 500.0):
        scenario = Scenario(
            failures=[Failure(joint=7)],
            numerics=Numerics(sgn_smoothing_m_s=5e-3),
            effects={"reference_stop_Nm_per_rad": gain},
            stop=Stop(time_limit_s=3.0),
        )
        ref = simulate_reference(scenario, plant_numbers().geometry, rtol=1e-5, atol=1e-7)
        reach[gain] = np.abs(ref.q[:, 6]).max() - LIMIT_RAD
    assert reach[20.0] > 0.0 and reach[20.0] > 2.0 * max(reach[500.0], 0.0)  # measured 0.022 and 0.0074 rad


def test_a_working_joint_takes_the_torque_of_the_path_it_follows():
    """The reference's working-joint torques (Eq. 1's rows of the prescribed joints, which LabForms' linkage reads):
    joint 7 made to follow the path it took when free takes exactly its free law's torque, -c_joint q_dot (inside the
    limit), and the head moves as it did (measured: 4e-6 N m of 0.07, 1.4e-6 m)."""
    from rc1_drake.engine.dynamics import plant_numbers

    geometry = plant_numbers().geometry
    free = Scenario(failures=[Failure(joint=7)], stop=Stop(time_limit_s=1.5), numerics=Numerics(sgn_smoothing_m_s=5e-3))
    grid = np.arange(0.0, 1.5 + 1e-9, 0.002)
    loose = simulate_reference(free, geometry, at_rest="head", t_eval=grid, rtol=1e-9, atol=1e-11)
    assert np.abs(loose.q[:, 6]).max() < math.radians(38.0)  # inside the limit: no stop torque
    held = simulate_reference(
        dataclasses.replace(free, failures=[]), geometry, at_rest="head", t_eval=grid, joint_path=(loose.t, loose.q),
        rtol=1e-9, atol=1e-11,
    )  # fmt: skip
    inner = slice(50, -50)  # away from the spline's ends
    passive = -free.friction.c_joint * loose.z_dot[inner, 9]
    np.testing.assert_allclose(held.joint_torque[inner, 6], passive, atol=1e-4 * np.abs(passive).max() + 1e-5)
    others = np.arange(13) != 6
    np.testing.assert_allclose(held.joint_torque[inner][:, others], loose.joint_torque[inner][:, others], atol=1e-4)
    assert np.abs(held.head_xy - loose.head_xy).max() < 1e-4
    assert np.all(loose.joint_torque[:, 6] == 0.0)


def test_lab_forms_read_what_another_labs_sensors_would(tmp_path):
    """LabForms (issue 67's forms of sensor): hand values of the marker's lever arm, the camera's scale and the
    converter's step; on a reference campaign, a linkage's reading leads the angle by compliance x torque (so a
    stiffer linkage reads closer to the truth), and a value out of range is refused naming its key."""
    from rc1_drake.config import Rc1Error
    from rc1_drake.synthesize import Case, LabForms, Noise, synthesize_campaign

    lab = LabForms(camera_marker_m=0.05, camera_scale_error=0.01, potentiometer_step_deg=0.5)
    pose = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, math.pi / 2]])
    np.testing.assert_allclose(lab.camera(pose), [[1.05 * 1.01, 2.02, 0.0], [0.0, 0.0505, math.pi / 2]], atol=1e-12)
    np.testing.assert_allclose(lab.quantized(np.radians([0.2, 0.3, -0.74])), np.radians([0.0, 0.5, -0.5]))
    with pytest.raises(Rc1Error, match=r"^synthesize: effects.reference_camera_marker_m: must lie in \[-0.1, 0.1\]"):
        LabForms.from_effects({"reference_camera_marker_m": 0.5})
    silent = Noise().scaled(0.0)
    readings, starts = {}, {}
    for compliance in (0.0, 0.01, 0.02):
        campaign = synthesize_campaign(
            tmp_path / f"c{compliance}", design=[Case([], 1, seconds=1.0)], truth_model="reference", noise=silent,
            effects={"reference_linkage_rad_per_Nm": compliance}, seed=3,
        )  # fmt: skip
        readings[compliance] = campaign.trials[0].q
        starts[compliance] = campaign.trials[0].initial_head_pose
    lead = {c: readings[c] - readings[0.0] for c in (0.01, 0.02)}
    assert 0.001 < np.abs(lead[0.01]).max() < 0.05  # rad: N m torques through 0.01 rad/N m
    np.testing.assert_allclose(lead[0.02], 2.0 * lead[0.01], atol=1e-9)
    marked = synthesize_campaign(
        tmp_path / "marked", design=[Case([], 1, seconds=1.0)], truth_model="reference", noise=silent,
        effects={"reference_camera_marker_m": 0.04}, seed=3,
    ).trials[0]  # fmt: skip
    yaw = starts[0.0][2]  # the start pose is the camera's: the marker's, 4 cm ahead along the head's axis
    np.testing.assert_allclose(marked.initial_head_pose, starts[0.0] + [0.04 * np.cos(yaw), 0.04 * np.sin(yaw), 0.0])
