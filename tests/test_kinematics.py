"""The planar kinematics kernels agree with Drake's own kinematics of the plant (an independent check)."""

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import DiagramBuilder

from rc1_drake.kinematics import module_motion, module_positions, module_yaws, wheel_kinematics
from rc1_drake.model import add_rc1_plant


@pytest.fixture(scope="module")
def rc1():
    return add_rc1_plant(DiagramBuilder(), time_step=5e-4)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_modules_and_wheels_match_drake(rc1, seed):
    plant, g = rc1.plant, rc1.geometry
    context = plant.CreateDefaultContext()
    x = np.random.default_rng(seed).normal(scale=0.6, size=32)
    plant.SetPositionsAndVelocities(context, x)
    phi, phi_dot, p, v = module_motion(x, g)
    for k in range(14):
        body = plant.GetBodyByName(f"module_{k + 1}")
        X = body.EvalPoseInWorld(context)
        V = body.EvalSpatialVelocityInWorld(context)
        assert np.allclose([p[k].real, p[k].imag], X.translation()[:2])
        assert np.isclose(
            np.arctan2(np.sin(phi[k]), np.cos(phi[k])),
            np.arctan2(X.rotation().matrix()[1, 0], X.rotation().matrix()[0, 0]),
        )
        assert np.allclose([v[k].real, v[k].imag], V.translational()[:2])
        assert np.isclose(phi_dot[k], V.rotational()[2])
    assert np.allclose(module_positions(complex(x[0], x[1]), module_yaws(x[2], x[3:16]), g), p)
    wk = wheel_kinematics(x, g)
    for w, k in enumerate(g.wheel_module):
        frame = plant.GetFrameByName(f"wheel_{k + 1}")
        J = plant.CalcJacobianTranslationalVelocity(
            context, JacobianWrtVariable.kV, frame, np.zeros(3), plant.world_frame(), plant.world_frame()
        )
        assert np.allclose(wk.jacobian[w].real, J[0]) and np.allclose(wk.jacobian[w].imag, J[1])
        assert np.allclose([wk.position[w].real, wk.position[w].imag], frame.CalcPoseInWorld(context).translation()[:2])
        R = frame.CalcPoseInWorld(context).rotation().matrix()
        assert np.allclose([wk.direction[w].real, wk.direction[w].imag], R[:2, 0])
