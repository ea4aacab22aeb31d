"""The discrepancy model (discrepancy.py): its shapes against hand values and their rates against central
differences, its sites by hand, both engines on it, and a physical check against a scalar equation."""

import dataclasses
import math

import numpy as np
import pytest
from test_engine import assert_equivalent, both, short
from test_mechanisms import assert_rolls_down_a_floor_against_its_scalar_equation

from rc1_drake.config import Failure, Friction, Gait, Scenario, Stop
from rc1_drake.discrepancy import (
    GROUPS,
    NJK,
    NSK,
    NUM_SITES,
    NUM_TERMS,
    SITE_GROUP,
    joint_shapes,
    site_coefficients,
    site_shape_rates,
    site_shapes,
    term_names,
)
from rc1_drake.effects import LIBRARY, candidate_names, model_setup
from rc1_drake.engine.dynamics import plant_numbers
from rc1_drake.friction import discrepancy_slice, friction_parameters, site_jacobians, tail_end_jacobian
from rc1_drake.protocol import simulate

# Nonzero terms of every kind, for the engines and the tangent: a term per group and the failed joint's four.
SOME = {
    "discrepancy_tail_dry_long_N": 0.8,
    "discrepancy_front_side_by_long_N_s_per_m": 0.6,
    "discrepancy_middle_drag_lat_N_s_per_m": -0.8,
    "discrepancy_rear_dry_lat_N": 0.3,
    "discrepancy_head_push_lat_N": 0.3,
    "discrepancy_head_drag_long_N_s_per_m": 0.5,
    "discrepancy_rear_push_long_N": -0.2,
    "discrepancy_failed_joint_bias_Nm": 0.05,
    "discrepancy_failed_joint_spring_Nm_per_rad": 0.3,
    "discrepancy_failed_joint_drag_Nm_s_per_rad": 0.02,
    "discrepancy_failed_joint_dry_Nm": 0.03,
}


def test_the_shapes_by_hand():
    """At u = (0.3, -0.4) m/s, eps = 0.01 m/s: each kind's force at unit coefficient."""
    u_long, u_lat, eps = 0.3, -0.4, 0.01
    s_long, s_lat = u_long / math.hypot(u_long, eps), u_lat / math.hypot(u_lat, eps)
    expected = np.array(
        [
            [-0.3, 0.0, -s_long, 0.0, 0.0, 1.0, 0.0, -0.09, 0.0],  # f_long
            [0.0, 0.4, 0.0, -s_lat, 0.3, 0.0, 1.0, 0.0, 0.16],  # f_lat
        ]
    )
    np.testing.assert_allclose(site_shapes(u_long, u_lat, eps), expected, rtol=1e-14)
    assert [k for _, k, _, _ in term_names()[:NSK]] == [
        "drag_long", "drag_lat", "dry_long", "dry_lat", "side_by_long", "push_long", "push_lat", "quad_long", "quad_lat"
    ]  # fmt: skip
    q, q_dot = 0.2, -0.5
    np.testing.assert_allclose(joint_shapes(q, q_dot, 0.01), [1.0, -0.2, 0.5, 0.5 / math.hypot(0.5, 0.01)], rtol=1e-14)


@pytest.mark.parametrize("u", [(0.3, -0.4), (-0.004, 0.002), (0.0, 0.0)])
def test_the_shapes_rates_match_central_differences(u):
    eps, h = 0.01, 1e-7
    along, across = site_shape_rates(*u, eps)
    for rate, step in ((along, (h, 0.0)), (across, (0.0, h))):
        expected = site_shapes(u[0] + step[0], u[1] + step[1], eps) - site_shapes(u[0] - step[0], u[1] - step[1], eps)
        np.testing.assert_allclose(rate, expected / (2 * h), atol=1e-6)


def test_groups_and_terms_line_up_with_the_parameter_vector():
    assert NUM_TERMS == len(GROUPS) * NSK + NJK == len(term_names())
    assert sorted(s for sites in GROUPS.values() for s in sites) == list(range(NUM_SITES))  # each site once
    theta = np.arange(NUM_TERMS, dtype=float)
    per_site = site_coefficients(theta)
    for s in range(NUM_SITES):
        np.testing.assert_array_equal(per_site[s], theta[SITE_GROUP[s] * NSK : (SITE_GROUP[s] + 1) * NSK])
    names = candidate_names(["discrepancy"])
    assert len(names) == NUM_TERMS and not set(names) & set(candidate_names(["physical", "study"]))
    geometry = plant_numbers().geometry
    key = "discrepancy_tail_dry_long_N"
    params = friction_parameters(
        friction=Friction(), sgn_smoothing_m_s=0.01, setup=model_setup({key: 0.7}), geometry=geometry
    )
    block = params[discrepancy_slice(len(geometry.wheel_module))]
    assert block[LIBRARY["discrepancy_tail_dry_long"].index] == 0.7 and np.count_nonzero(block) == 1


def test_the_sites_are_the_heads_centre_the_wheels_and_the_tails_end_by_hand():
    """The straight snake along +x: each site's module frame is the world's, so its rows are the world velocity
    Jacobian of its point; the head's centre moves with the planar joint's x and y alone, the tail's end as the
    tether's point (test_mechanisms), a wheel of module k as its centre 0.125 (k - 1) m behind the head."""
    geometry = plant_numbers().geometry
    x = np.zeros(32)
    along, across = site_jacobians(x, geometry.arrays)
    assert along.shape == across.shape == (NUM_SITES, 16)
    np.testing.assert_allclose(along[0], np.eye(16)[0], atol=1e-15)
    np.testing.assert_allclose(across[0], np.eye(16)[1], atol=1e-15)
    tail = tail_end_jacobian(x, geometry.arrays)
    np.testing.assert_allclose(along[-1], tail[0], atol=1e-15)
    np.testing.assert_allclose(across[-1], tail[1], atol=1e-15)
    wheel = 1  # module 2's
    behind = -0.125 + geometry.wheel_offset[0].real
    joint_1 = -0.0625
    np.testing.assert_allclose(across[wheel], np.r_[0.0, 1.0, behind, behind - joint_1, np.zeros(12)], atol=1e-12)


def test_both_engines_agree_on_every_kind_of_term_and_the_terms_change_the_run():
    scenario = short(Scenario(failures=[Failure(joint=7)], effects=dict(SOME)), seconds=2.0)
    drake, compiled = both(scenario)
    assert_equivalent(drake, compiled)
    plain = both(dataclasses.replace(scenario, effects={}))[1]
    assert np.abs(compiled.state[-1] - plain.state[-1]).max() > 1e-3


def test_a_tail_drag_on_the_snake_rolling_down_a_floor_follows_its_scalar_equation():
    """The tail's longitudinal dry term acts as a tether there on a snake rolling straight (eps: the wheels')."""
    assert_rolls_down_a_floor_against_its_scalar_equation("discrepancy_tail_dry_long_N")


def test_a_failed_joints_spring_and_bias_hold_it_where_they_balance():
    """A free joint 7 of a snake on a frictionless floor (no gait) with the discrepancy's bias b, spring k and drag:
    the two halves turn about it until it rests at q = b / k, the other servos holding their joints straight."""
    bias, spring = 0.2, 2.0
    scenario = Scenario(
        gait=Gait(amplitude_deg=0.0),
        friction=Friction(mu_lat=0.0, mu_long=0.0, c_lat=0.0, c_long=0.0),
        failures=[Failure(joint=7)],
        effects={
            "discrepancy_failed_joint_bias_Nm": bias,
            "discrepancy_failed_joint_spring_Nm_per_rad": spring,
            "discrepancy_failed_joint_drag_Nm_s_per_rad": 0.5,
        },
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=4.0),
    )
    run = simulate(scenario=scenario)
    assert run.q[-1, 6] == pytest.approx(bias / spring, rel=0.01)
    assert np.abs(np.delete(run.q[-1], 6)).max() < 0.01
