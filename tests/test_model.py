"""models/rc1.sdf as Drake reads it: the numbers of paper section 2-3 and the issue's conventions."""

import math

import numpy as np
import pytest
from pydrake.geometry import Role
from pydrake.systems.framework import DiagramBuilder

from rc1_drake.model import add_rc1_plant


@pytest.fixture(scope="module")
def rc1():
    return add_rc1_plant(DiagramBuilder(), time_step=5e-4)


def test_modules_and_joints(rc1):
    plant = rc1.plant
    bodies = [plant.GetBodyByName(f"module_{k}") for k in range(1, 15)]
    context = plant.CreateDefaultContext()
    assert all(math.isclose(b.get_mass(context), 0.286) for b in bodies)
    # 14 modules of 0.125 m: the joints sit 0.125 m apart, module centres mid-way.
    g = rc1.geometry
    assert np.allclose(g.joint_in_parent, -0.0625) and np.allclose(g.joint_in_child, 0.0625)
    assert math.isclose(sum(abs(g.joint_in_parent)) + sum(abs(g.joint_in_child)) + 0.125, 1.75)
    for i, joint in enumerate(rc1.joints, start=1):
        assert joint.name() == f"joint_{i}"
        assert joint.parent_body().name() == f"module_{i}" and joint.child_body().name() == f"module_{i + 1}"
        assert np.allclose(joint.revolute_axis(), [0, 0, 1])
        assert np.allclose(joint.position_upper_limits(), math.radians(38))
        assert np.allclose(joint.position_lower_limits(), -math.radians(38))
        assert np.allclose(joint.velocity_upper_limits(), math.radians(140))
    assert np.allclose(rc1.effort_limit, 1.19) and len(rc1.effort_limit) == 13


def test_inertia_keeps_the_paper_yaw_value_and_is_physical(rc1):
    plant = rc1.plant
    context = plant.CreateDefaultContext()
    inertia = plant.GetBodyByName("module_5").CalcSpatialInertiaInBodyFrame(context)
    moments = inertia.CalcRotationalInertia().get_moments()
    assert math.isclose(moments[2], 5.362e-4)
    assert np.allclose(moments[:2], 5.362e-4 / 2)  # the smallest valid pair: a flat plate
    assert inertia.IsPhysicallyValid()


def test_wheels_on_modules_2_to_14_with_visuals(rc1):
    plant = rc1.plant
    assert not plant.HasFrameNamed("wheel_1")
    for k in range(2, 15):
        frame = plant.GetFrameByName(f"wheel_{k}")
        assert frame.body().name() == f"module_{k}"
        assert np.allclose(frame.GetFixedPoseInBodyFrame().translation(), 0)  # mid-section
    assert list(rc1.geometry.wheel_module) == list(range(1, 14))
    inspector = rc1.scene_graph.model_inspector()
    for k, expected in ((1, 1), (2, 3), (14, 3)):  # the head: a box; others: a box and two wheels
        body = plant.GetBodyByName(f"module_{k}")
        visuals = inspector.GetGeometries(plant.GetBodyFrameIdOrThrow(body.index()), Role.kIllustration)
        assert len(visuals) == expected


def test_planar_base_joint(rc1):
    base = rc1.base_joint
    assert base.type_name() == "planar" and base.child_body().name() == "module_1"
    assert rc1.plant.num_positions() == 16 and rc1.plant.num_velocities() == 16
