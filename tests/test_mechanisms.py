"""Issue 41's candidate mechanisms of the J2 circling: a failed joint's compliant stop and a cantilevered head."""

import dataclasses
import math

import numpy as np
from test_engine import assert_equivalent, both, short

from rc1_drake.config import JOINT_LIMIT_DEG, NUM_JOINTS, Failure, Friction, Scenario
from rc1_drake.effects import model_setup
from rc1_drake.engine.dynamics import plant_numbers
from rc1_drake.friction import FAILED, FREE, compliant_stop, friction_parameters, normal_slice

K, D, MARGIN_DEG = 20.0, 0.1, 5.0
STOP = {"stop_k_Nm_per_rad": K, "stop_d_Nm_s_per_rad": D, "stop_margin_deg": MARGIN_DEG}


def params_of(effects, free_joint=None):
    geometry = plant_numbers().geometry
    setup = model_setup(effects)
    params = friction_parameters(friction=Friction(), sgn_smoothing_m_s=1e-3, setup=setup, geometry=geometry)
    if free_joint:
        params[FAILED][free_joint - 1] = FREE
    return params


def test_the_stop_pushes_back_past_its_onset_only_in_a_free_joint():
    params = params_of(STOP, free_joint=2)
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


def test_both_engines_agree_on_a_free_joint_2_in_its_compliant_stop():
    scenario = short(Scenario(failures=[Failure(joint=2)], effects=dict(STOP)), seconds=2.0)
    drake, compiled = both(scenario)
    assert_equivalent(drake, compiled)
    onset = JOINT_LIMIT_DEG - MARGIN_DEG
    assert np.abs(np.degrees(compiled.q[:, 1])).max() > onset  # the stop was reached
    plain = both(dataclasses.replace(scenario, effects={}))[1]
    assert np.abs(compiled.q[:, 1] - plain.q[:, 1]).max() > 1e-3  # and it changed the run
