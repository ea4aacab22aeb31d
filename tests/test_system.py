"""System tests of the Drake Diagram that would fail if the physics were wrong."""

import dataclasses
import math

import numpy as np
import pytest
from conftest import with_stop

from rc1_drake.config import Failure, Friction, Gait, Scenario, Start
from rc1_drake.metrics import summarize

LIMIT = math.radians(38.0)


def test_nominal_gait_moves_forward(simulate_cached, nominal_scenario):
    run = simulate_cached(nominal_scenario)
    # At least 2 m forward within 15 s; in fact it reaches the 3.18 m line in about 10 s (0.32 m/s).
    assert run.stop_reason == "crossed" and run.t[-1] < 15.0
    assert run.head_xy[-1, 0] >= 3.18


def test_isotropic_friction_gives_no_forward_progress(simulate_cached):
    # Lateral coefficients equal to the longitudinal ones: no anisotropy, no propulsion.
    friction = Friction(mu_lat=0.12, c_lat=0.14)
    run = simulate_cached(with_stop(Scenario(friction=friction), line_x_m=None, time_limit_s=15.0))
    assert run.head_xy[-1, 0] < 0.1  # measured: about 1.1 m backward


def test_mirrored_gait_mirrors_the_path(simulate_cached, nominal_scenario):
    run = simulate_cached(nominal_scenario)
    mirrored = simulate_cached(dataclasses.replace(nominal_scenario, gait=Gait(amplitude_deg=-38.0)))
    assert len(run.t) == len(mirrored.t)
    assert np.abs(run.head_xy[:, 0] - mirrored.head_xy[:, 0]).max() < 0.01
    assert np.abs(run.head_xy[:, 1] + mirrored.head_xy[:, 1]).max() < 0.01


def test_rotated_start_rotates_the_path(simulate_cached):
    base = with_stop(Scenario(), line_x_m=None, time_limit_s=6.0)
    angle = 30.0
    rotated = dataclasses.replace(base, start=Start(heading_deg=angle))
    a, b = simulate_cached(base), simulate_cached(rotated)
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    expected = a.head_xy @ np.array([[c, s], [-s, c]])
    assert np.abs(b.head_xy - expected).max() < 0.01
    assert np.allclose(np.unwrap(b.head_yaw) - np.unwrap(a.head_yaw), math.radians(angle), atol=1e-3)
    assert np.linalg.norm(a.head_xy[-1]) > 1.5  # it did go somewhere


def test_failed_joint_stays_within_its_limits_and_servos_within_torque(simulate_cached, joint7_scenario):
    run = simulate_cached(joint7_scenario)
    q7 = run.q[:, 6]
    assert np.abs(q7).max() <= LIMIT + math.radians(0.5)
    assert np.abs(q7).max() > math.radians(20)  # it does swing: it is free, not held
    assert np.all(run.servo_torque[:, 6] == 0.0)  # the failed servo applies nothing
    assert np.abs(run.servo_torque).max() <= 1.19 + 1e-12
    assert np.abs(run.servo_torque).max() > 1.0  # the working servos do reach their limit
    assert np.abs(run.q).max() <= LIMIT + math.radians(0.5)


def test_a_failure_mid_run_switches_at_its_time(simulate_cached, nominal_scenario):
    late = dataclasses.replace(nominal_scenario, failures=[Failure(joint=7, time_s=3.0)])
    run, nominal = simulate_cached(late), simulate_cached(nominal_scenario)
    before = run.t < 3.0 - 1e-9
    same = np.searchsorted(nominal.t, run.t[before])
    assert np.array_equal(nominal.t[same], run.t[before])
    assert np.array_equal(run.state[before], nominal.state[same])  # identical until it fails
    assert np.abs(run.servo_torque[before, 6]).max() > 0.1
    assert np.all(run.servo_torque[run.t > 3.0 + 1e-9, 6] == 0.0)
    # Joint 7 now moves as the wheels push it, no longer as its servo commanded.
    after = (run.t > 4.0) & (run.t < 9.0)
    same = np.searchsorted(nominal.t, run.t[after])
    assert np.abs(run.q[after, 6] - nominal.q[same, 6]).max() > math.radians(1.0)


def test_circling_stop_rule(simulate_cached):
    scenario = with_stop(Scenario(gait=Gait(bias_deg=12.0)), revolutions=1.0, time_limit_s=30.0)
    run = simulate_cached(scenario)
    summary = summarize(run)
    assert summary.outcome == "circling" and summary.t_final_s < 30.0
    assert summary.revolutions == pytest.approx(1.0, abs=0.01)
    assert 0.5 < summary.circle_diameter_m < 2.0  # measured: about 1.1 m


def test_head_imu_reads_the_head_yaw_rate(simulate_cached, nominal_scenario):
    from rc1_drake.protocol import Session

    session = Session(nominal_scenario)
    context = session.simulator.get_mutable_context()
    from rc1_drake.protocol import configure_context

    configure_context(session.built, context, nominal_scenario)
    session.simulator.AdvanceTo(0.5)
    imu = session.built.diagram.GetOutputPort("head_yaw_rate").Eval(context)[0]
    state = session.built.diagram.GetOutputPort("plant_state").Eval(context)
    assert imu == state[18] and abs(imu) > 0.01


def test_servos_track_the_gait(simulate_cached, nominal_scenario):
    from rc1_drake.gait import serpenoid

    run = simulate_cached(nominal_scenario)
    commanded = np.array([serpenoid(t, nominal_scenario.gait)[0] for t in run.t])
    error = np.degrees(commanded - run.q)
    assert np.sqrt(np.mean(error**2)) < 1.0  # measured: 0.53 deg RMS
    assert np.abs(error).max() < 5.0  # measured: 3.6 deg, where a servo saturates
