"""Issue 41's candidate mechanisms of the J2 circling: a failed joint's compliant stop, a cantilevered head and a
tether dragged behind the tail."""

import dataclasses
import math

import numpy as np
import pytest
from test_engine import assert_equivalent, both, short

from rc1_drake.config import JOINT_LIMIT_DEG, NUM_JOINTS, Failure, Friction, Gait, Scenario, Stop
from rc1_drake.effects import model_setup
from rc1_drake.engine.dynamics import plant_numbers
from rc1_drake.engine.session import CompiledSession
from rc1_drake.friction import (
    FAILED,
    FREE,
    TETHER_EPS_M_S,
    TETHER_N,
    compliant_stop,
    friction_parameters,
    normal_slice,
    tail_end_jacobian,
)
from rc1_drake.protocol import simulate

K, D, MARGIN_DEG = 20.0, 0.1, 5.0
STOP = {"stop_compliance_rad_per_Nm": 1.0 / K, "stop_d_Nm_s_per_rad": D}  # at the limit, in place of it


def params_of(effects, free_joint=None):
    geometry = plant_numbers().geometry
    setup = model_setup(effects)
    params = friction_parameters(friction=Friction(), sgn_smoothing_m_s=1e-3, setup=setup, geometry=geometry)
    if free_joint:
        params[FAILED][free_joint - 1] = FREE
    return params


def test_the_stop_pushes_back_past_its_onset_only_in_a_free_joint():
    params = params_of({**STOP, "stop_margin_deg": MARGIN_DEG}, free_joint=2)
    onset = math.radians(JOINT_LIMIT_DEG - MARGIN_DEG)
    x = np.zeros(32)
    x[3 + 1], x[3 + 2] = onset + 0.01, onset + 0.01  # joint 2 free, joint 3 working: both past the onset
    spring, rate = compliant_stop(x, params, 1e-3)
    assert spring[3 + 1] == -K * 0.01 * (1 + 1e-9) or math.isclose(spring[3 + 1], -K * 0.01, rel_tol=1e-9)
    assert rate[3 + 1] == D + 1e-3 * K
    assert spring[3 + 2] == 0.0 and rate[3 + 2] == 0.0
    x[3 + 1] = -(onset + 0.02)
    assert math.isclose(compliant_stop(x, params, 1e-3)[0][3 + 1], K * 0.02, rel_tol=1e-9)
    x[3 + 1] = onset - 0.01
    assert not compliant_stop(x, params, 1e-3)[0].any()
    assert not compliant_stop(x, params_of({}, free_joint=2), 1e-3)[0].any()  # k = 0: the stiff limit alone


def test_a_cantilevered_head_loads_wheel_2_and_lifts_wheel_3_by_the_excess():
    geometry = plant_numbers().geometry
    nw = len(geometry.wheel_module)
    base = params_of({})[normal_slice(nw)]
    head = geometry.module_mass[0] * 9.81
    moved = params_of({"head_on_wheel2": 1.5})[normal_slice(nw)] - base
    assert list(geometry.wheel_module[:2]) == [1, 2]  # modules 2 and 3 (0-based 1, 2) carry the first wheels
    np.testing.assert_allclose(moved[:2], [1.5 * head, -0.5 * head])
    assert not moved[2:].any()
    assert len(base) == NUM_JOINTS


def test_both_engines_agree_on_a_free_joint_2_swinging_past_38_deg_into_its_compliant_stop():
    scenario = short(Scenario(failures=[Failure(joint=2)], effects=dict(STOP)), seconds=2.0)
    drake, compiled = both(scenario)
    assert_equivalent(drake, compiled)
    assert np.abs(np.degrees(drake.q[:, 1])).max() > JOINT_LIMIT_DEG + 0.5  # the stop, not the stiff limit
    plain = both(dataclasses.replace(scenario, effects={}))[1]
    assert np.abs(np.degrees(plain.q[:, 1])).max() <= JOINT_LIMIT_DEG + 0.05
    assert np.abs(compiled.q[:, 1] - plain.q[:, 1]).max() > 1e-3  # and it changed the run


def test_a_stiff_compliant_stop_converges_with_the_stiff_limit_it_replaces():
    """Nested at compliance 0 (the same run), and continuous there as the step shrinks: a stop of 1e-5 rad/N m is
    a rigid limit met inside the implicit friction solve, where the plant's limit is met after it (engine/step.py),
    so their runs differ by a splitting error that falls with the step (measured: 2.6, 1.4, 0.7 cm at the head)."""
    session = CompiledSession()
    scenario = Scenario(failures=[Failure(joint=2)], stop=Stop(time_limit_s=2.0))
    plain = session.simulate(scenario)
    assert np.array_equal(
        session.simulate(dataclasses.replace(scenario, effects={**STOP, "stop_compliance_rad_per_Nm": 0.0})).q, plain.q
    )
    apart = []
    for dt in (1e-3, 5e-4, 2.5e-4):
        fine = dataclasses.replace(scenario, numerics=dataclasses.replace(scenario.numerics, time_step_s=dt))
        stiff = dataclasses.replace(fine, effects={"stop_compliance_rad_per_Nm": 1e-5})
        apart.append(np.hypot(*(session.simulate(stiff).head_xy[-1] - session.simulate(fine).head_xy[-1])))
    assert apart[0] > 0.01 and apart[1] < 0.65 * apart[0] and apart[2] < 0.65 * apart[1]


def test_the_tail_tethers_point_is_the_tails_end_and_its_lever_arms_by_hand():
    """The straight snake along +x (module pitch 0.125 m, joints 0.0625 m behind each centre): the tail's end sits
    1.6875 m behind the head's centre; a unit rate of the head's yaw or of joint j moves it along y by its lever arm
    (its x from the head's centre, or from joint j), and the drag reaches each coordinate through that row."""
    geometry = plant_numbers().geometry
    rear = -(13 * 0.125 + 0.0625)
    jac = tail_end_jacobian(np.zeros(32), geometry.arrays)
    joints = -0.0625 - 0.125 * np.arange(NUM_JOINTS)
    np.testing.assert_allclose(jac[0], np.r_[1.0, 0.0, np.zeros(14)], atol=1e-15)
    np.testing.assert_allclose(jac[1], np.r_[0.0, 1.0, rear, rear - joints], atol=1e-15)
    params = params_of({"tail_tether_N": 0.7})
    assert params[TETHER_N] == 0.7 and not params_of({})[TETHER_N]
    u = jac @ np.r_[0.0, 0.0, 0.1, np.zeros(13)]  # turning in place: the end moves along y at 0.1 * rear
    f_y = -0.7 * u[1] / math.hypot(u[1], TETHER_EPS_M_S)
    np.testing.assert_allclose(jac.T @ np.array([0.0, f_y]), np.r_[0.0, f_y, rear * f_y, (rear - joints) * f_y],
                               rtol=1e-12)  # fmt: skip


def test_both_engines_agree_on_a_tether_and_it_changes_the_run():
    scenario = short(Scenario(failures=[Failure(joint=7)], effects={"tail_tether_N": 2.0}), seconds=2.0)
    drake, compiled = both(scenario)
    assert_equivalent(drake, compiled)
    plain = both(dataclasses.replace(scenario, effects={}))[1]
    assert np.abs(compiled.state[-1] - plain.state[-1]).max() > 1e-4  # it changed the run


def assert_rolls_down_a_floor_against_its_scalar_equation(key: str, eps_m_s=None):
    """10 deg downhill toward +x, the straight snake (no c_long), with a drag of T = 0.5 N at the tail's end set by
    effect parameter `key`: 14 m v' = 14 m g sin a - 13 mu_long m g cos a - T v / sqrt(v^2 + eps^2), integrated here
    on its own, against the run (eps: the drag's smoothing, the wheels' when None)."""
    tension, alpha, mass = 0.5, math.radians(10.0), 0.286
    scenario = Scenario(
        gait=Gait(amplitude_deg=0.0),
        friction=dataclasses.replace(Friction(), c_long=0.0),
        effects={"ground_slope_deg": 10.0, "ground_slope_direction_deg": 0.0, key: tension},
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=1.0),
    )
    run = simulate(scenario=scenario)
    eps = scenario.numerics.sgn_smoothing_m_s if eps_m_s is None else eps_m_s
    dt, v = 1e-5, 0.0
    for _ in range(round(1.0 / dt)):
        drive = 14 * mass * 9.81 * math.sin(alpha) - 13 * 0.12 * mass * 9.81 * math.cos(alpha)
        v += dt * (drive - tension * v / math.hypot(v, eps)) / (14 * mass)
    assert run.state[-1, 16] == pytest.approx(v, rel=2e-3)
    assert abs(run.state[-1, 17]) < 1e-6


def test_the_snake_rolling_down_a_floor_with_a_tether_follows_its_scalar_equation():
    assert_rolls_down_a_floor_against_its_scalar_equation("tail_tether_N", TETHER_EPS_M_S)


LINKAGE = {"linkage_compliance_rad_per_Nm": 0.01, "linkage_damping_Nm_s_per_rad": 0.05}


def test_a_linkage_in_series_with_a_servo_by_hand():
    """The servo acts on its shaft, the linkage (1 / c) carries its torque to the joint: kp in series with 1 / c, its
    I and D terms scaled alike, the linkage's damping added; 0 leaves the servo; the replay's stiff joint becomes
    the spring 1 / c."""
    from rc1_drake.config import Servo
    from rc1_drake.effects import running_servo, sensor_model
    from rc1_drake.replay import REPLAY_SERVO

    linked = running_servo(Servo(kp_Nm_per_rad=20.0, ki_Nm_per_rad_s=5.0, kd_Nm_s_per_rad=0.2), LINKAGE)
    assert linked.kp_Nm_per_rad == pytest.approx(20.0 / 1.2)
    assert linked.ki_Nm_per_rad_s == pytest.approx(5.0 / 1.2)
    assert linked.kd_Nm_s_per_rad == pytest.approx(0.2 / 1.2 + 0.05)
    assert running_servo(Servo(), {"linkage_compliance_rad_per_Nm": 0.0}) == Servo()
    assert running_servo(REPLAY_SERVO, LINKAGE).kp_Nm_per_rad == pytest.approx(100.0, rel=1e-5)
    assert sensor_model(LINKAGE).linkage_rad_per_Nm == 0.01


def test_a_replay_through_the_linkage_agrees_on_both_engines_and_its_shafts_follow_the_readings():
    """The working joints lag their readings by c tau, while the shafts (joint + c tau, what the potentiometers
    read) follow the readings as the rigid joints did; the Drake engine builds the Diagram of the linked servo."""
    from conftest import first_seconds

    from rc1_drake.measurements import load_trial
    from rc1_drake.replay import Replayer, tracking_rms_deg

    trial = first_seconds(load_trial("data/paper_campaign/j7_1.json"), 2.0)
    compiled = Replayer(trial, engine="compiled")
    linked, rigid = compiled.run(Friction(), LINKAGE), compiled.run(Friction(), {})
    assert_equivalent(Replayer(trial, engine="drake").run(Friction(), LINKAGE), linked)
    working = [j - 1 for j in trial.working_joints]
    lag = math.degrees(float(np.abs(linked.q - rigid.q)[:, working].max()))
    assert lag > 0.2  # c tau of a few tenths of N m
    assert tracking_rms_deg(linked, trial) < tracking_rms_deg(rigid, trial) + 0.1 * lag


def test_a_replay_at_the_truths_linkage_recovers_what_the_rigid_replay_misses(tmp_path):
    """Drake-truth trials whose potentiometers read the shafts behind a 0.02 rad/N m linkage: the replay with the
    linkage lands the head far nearer the measured end than the rigid one."""
    from rc1_drake.compare import score_trial
    from rc1_drake.measurements import load_campaign
    from rc1_drake.replay import Replayer
    from rc1_drake.synthesize import Case, synthesize_campaign

    effects = {"linkage_compliance_rad_per_Nm": 0.02}
    stop = Stop(line_x_m=None, revolutions=None, time_limit_s=6.0)
    synthesize_campaign(tmp_path / "c", design=[Case([], 1), Case([7], 1)], stop=stop, seed=5, effects=effects)
    for trial in load_campaign(tmp_path / "c").trials:
        replayer = Replayer(trial)
        miss = {
            c: score_trial(trial, replayer.run(Friction(), {"linkage_compliance_rad_per_Nm": c})).eq6_error_pct
            for c in (0.0, 0.02)
        }
        assert miss[0.02] < 0.5 * miss[0.0], (trial.trial_id, miss)
