"""The start configuration of paper section 4."""

import math

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from rc1_drake.config import JOINT_LIMIT_DEG, Gait, Scenario, Start
from rc1_drake.gait import serpenoid
from rc1_drake.kinematics import module_motion
from rc1_drake.model import add_rc1_plant
from rc1_drake.protocol import initial_state


@pytest.mark.parametrize("heading_deg, offset_deg", [(0.0, 0.0), (25.0, 70.0)])
def test_start_configuration(heading_deg, offset_deg):
    geometry = add_rc1_plant(DiagramBuilder(), time_step=5e-4).geometry
    scenario = Scenario(gait=Gait(phase_offset_deg=offset_deg), start=Start(x_m=0.3, y_m=-0.2, heading_deg=heading_deg))
    x = initial_state(scenario, geometry)
    q, qd = serpenoid(0.0, scenario.gait)
    assert np.allclose(x[3:16], q) and np.allclose(x[19:32], qd)
    assert np.allclose(x[:2], [0.3, -0.2])  # the head centre at the start point
    phi, phi_dot, _, v = module_motion(x, geometry)
    assert phi.mean() == pytest.approx(math.radians(heading_deg))  # mean axis along the heading
    assert phi_dot.mean() == pytest.approx(0.0, abs=1e-12)  # ... and not turning
    m = geometry.module_mass
    assert abs((m * v).sum()) < 1e-12  # centre of mass at rest


def test_a_biased_gait_starts_within_the_joint_limits():
    geometry = add_rc1_plant(DiagramBuilder(), time_step=5e-4).geometry
    scenario = Scenario(gait=Gait(bias_deg=4.0))
    x = initial_state(scenario, geometry)
    commanded, commanded_rate = serpenoid(0.0, scenario.gait)
    limit = math.radians(JOINT_LIMIT_DEG)
    assert np.abs(commanded).max() > limit + math.radians(3)  # the gait commands joint 8 to 41.4 deg at t = 0
    q, q_dot = x[3:16], x[19:32]
    assert np.abs(q).max() <= limit + 1e-12
    inside = np.abs(commanded) < limit
    assert np.allclose(q[inside], commanded[inside]) and np.allclose(q_dot[inside], commanded_rate[inside])
    assert np.all(q[~inside] * q_dot[~inside] <= 0.0)  # a joint at its limit is not moving outward
