"""The step's O(n) matrix and solve (articulated.py) against the plant's mass matrix and the dense step matrix."""

import numpy as np
from pydrake.systems.framework import DiagramBuilder

from rc1_drake import friction as fr
from rc1_drake.articulated import articulated_matrix, articulated_solve, chain_inertias
from rc1_drake.config import Friction
from rc1_drake.effects import model_setup
from rc1_drake.engine.dynamics import chain_terms, plant_numbers
from rc1_drake.kinematics import chain_frames
from rc1_drake.model import add_rc1_plant, module_inertias, set_payload


def _state(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=32)
    x[:2] *= 2.0
    x[3:16] *= 0.6
    return x, rng


def test_the_modules_inertias_about_the_head_give_the_plants_mass_matrix():
    """sum_k J_k^T B_k J_k (module twists at the head's centre) is MultibodyPlant's M(q), payload included."""
    rc1 = add_rc1_plant(DiagramBuilder(), time_step=1e-3)
    plant = rc1.plant
    context = plant.CreateDefaultContext()
    set_payload(plant, context, 6, 0.3)
    bodies = module_inertias(plant, context)
    jp, jc, *_ = rc1.geometry.arrays
    for seed in range(3):
        x, _ = _state(seed)
        plant.SetPositionsAndVelocities(context, x)
        inertia, motion = chain_inertias(chain_frames(x, jp, jc), bodies)
        expected = plant.CalcMassMatrix(context)
        np.testing.assert_allclose(articulated_matrix(inertia, np.zeros(16), motion), expected, atol=1e-12)


def test_the_recursion_solves_what_a_dense_factorization_solves_and_refuses_an_indefinite_matrix():
    numbers = plant_numbers()
    jp, jc, *_ = numbers.geometry.arrays
    bodies = np.column_stack([numbers.masses(), numbers.central_yaw_inertia, numbers.com.real, numbers.com.imag])
    for seed in range(3):
        x, rng = _state(seed)
        inertia, motion = chain_inertias(chain_frames(x, jp, jc), bodies)
        for k in range(len(inertia)):  # a wheel's damping on each module: positive semidefinite, rank 2
            rows = rng.normal(size=(2, 3))
            inertia[k] += rows.T @ np.diag(rng.uniform(0.0, 5.0, 2)) @ rows
        joint_rate = np.r_[np.zeros(3), rng.uniform(0.0, 2.0, 13)]
        rhs = rng.normal(size=16)
        matrix = articulated_matrix(inertia, joint_rate, motion)
        np.testing.assert_allclose(articulated_solve(inertia, joint_rate, motion, rhs), np.linalg.solve(matrix, rhs))
    joint_rate[9] = -1e3  # not definite: a pivot falls below zero
    assert articulated_solve(inertia, joint_rate, motion, rhs).shape == (0,)


def test_the_step_matrix_body_by_body_is_the_dense_one():
    """step_system's modules' inertias with the wheels', head drag's and tether's rates, and the joints' (a failed
    joint's friction, the servos), assembled densely, are assemble_step's matrix; the forces are the same."""
    numbers = plant_numbers()
    geometry = numbers.geometry
    jp, jc, *_ = geometry.arrays
    mass, inertia, com = numbers.masses(), numbers.central_yaw_inertia, numbers.com
    bodies = np.column_stack([mass, inertia, com.real, com.imag])
    setup = model_setup({"lateral_friction_asymmetry": 0.2, "head_drag_mu": 0.3, "tail_tether_N": 0.5})
    params = fr.friction_parameters(friction=Friction(), sgn_smoothing_m_s=0.01, setup=setup, geometry=geometry)
    params[fr.FAILED][6] = fr.FREE
    params[fr.JOINT_COULOMB] = 0.05
    for seed in range(3):
        x, rng = _state(seed)
        x[16:] *= 0.1
        M, bias, _ = chain_terms(x, mass, inertia, com, jp, jc, 0j)
        command = rng.normal(scale=0.5, size=13)
        laws, *_ = fr.friction_problem(
            x, -bias, M, 5e-4, params, command, numbers.effort_limit, np.array([20.0, 0.2]), geometry.arrays, bodies
        )
        for tangent in (False, True):
            force, matrix, linear = fr.assemble_step(x[16:], tangent, laws)
            force_local, (_, body, joint), linear_local = fr.step_system(x[16:], tangent, laws)
            np.testing.assert_allclose(force_local, force, atol=1e-12)
            np.testing.assert_array_equal(linear_local, linear)
            np.testing.assert_allclose(articulated_matrix(body, joint, laws.motion), matrix, atol=1e-10)
