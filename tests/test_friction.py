"""Friction kernels (paper Eqs. 4-5) against hand-computed values, and the implicit step's equations."""

import math

import numpy as np
import pytest

from rc1_drake.friction import implicit_friction_force, smooth_sign, wheel_friction_forces

PAPER = dict(mu_long=0.12, mu_lat=1.5, c_long=0.14, c_lat=3.75)
N = 0.286 * 9.81  # one module's weight


def test_hand_computed_forces_exact_sign():
    # A wheel rolling forward at 0.3 m/s and slipping left at 0.02 m/s:
    #   F_long = -(0.14 * 0.3 + 0.12 * 2.80566) = -0.378679 N
    #   F_lat  = -(3.75 * 0.02 + 1.5 * 2.80566) = -4.283490 N
    f_long, f_lat = wheel_friction_forces(
        np.array([0.3]), np.array([0.02]), normal_force=np.array([N]), eps=0.0, **PAPER
    )
    assert f_long[0] == pytest.approx(-0.378679, abs=1e-6)
    assert f_lat[0] == pytest.approx(-4.283490, abs=1e-6)
    # Backward and to the right: the signs flip, magnitudes stay (friction is odd in v).
    b_long, b_lat = wheel_friction_forces(
        np.array([-0.3]), np.array([-0.02]), normal_force=np.array([N]), eps=0.0, **PAPER
    )
    assert b_long[0] == pytest.approx(-f_long[0]) and b_lat[0] == pytest.approx(-f_lat[0])


def test_smoothing_is_the_sign_away_from_zero_and_zero_at_rest():
    eps = 1e-3
    assert smooth_sign(np.array([0.0]), eps)[0] == 0.0
    # v = 10 eps: 10 / sqrt(101) = 0.995037...
    assert smooth_sign(np.array([0.01]), eps)[0] == pytest.approx(10 / math.sqrt(101))
    assert smooth_sign(np.array([-1.0]), eps)[0] == pytest.approx(-1.0, abs=1e-6)
    f_long, _ = wheel_friction_forces(np.array([0.0]), np.array([0.0]), normal_force=np.array([N]), eps=eps, **PAPER)
    assert f_long[0] == 0.0


def _random_problem(seed, n=6, w=4):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    mass = a @ a.T + n * np.eye(n)
    jl, jt = rng.normal(size=(w, n)), rng.normal(size=(w, n))
    v = rng.normal(scale=0.05, size=n)
    return mass, np.ascontiguousarray(jl), np.ascontiguousarray(jt), v


@pytest.mark.parametrize("seed", [0, 1])
def test_implicit_step_solves_backward_euler(seed):
    mass, jl, jt, v = _random_problem(seed)
    dt, eps = 1e-3, 1e-3
    normal = np.full(len(jl), N)
    damping = np.zeros(len(v))
    damping[-1] = 0.045
    p_free = mass @ v + dt * np.linspace(-1, 1, len(v))
    tau = implicit_friction_force(
        jl, jt, damping, mass, p_free, v, dt, normal_force=normal, eps=eps, newton_steps=8, **PAPER
    )
    v_next = np.linalg.solve(mass, p_free + dt * tau)
    f_long, f_lat = wheel_friction_forces(jl @ v_next, jt @ v_next, normal_force=normal, eps=eps, **PAPER)
    expected = jl.T @ f_long + jt.T @ f_lat - damping * v_next
    assert np.allclose(tau, expected, rtol=1e-8, atol=1e-9)


def test_implicit_servos_solve_backward_euler_within_their_power():
    """Servos in the step (FrictionForces' PID): the torque is clamp(offset - rate v+, +-power) at the step's
    end velocity, one servo saturated and the others not, and the friction balances the rest of the step."""
    mass, jl, jt, v = _random_problem(5)
    n, dt, eps = len(v), 1e-3, 1e-3
    normal = np.full(len(jl), N)
    offset = np.array([0.0, 0.0, 0.3, -0.2, 5.0, 0.1])  # the fifth asks for far more than its power
    rate = np.array([0.0, 0.0, 0.25, 0.25, 0.25, 0.25])  # Kd + dt Kp
    power = np.array([0.0, 0.0, 1.19, 1.19, 1.19, 1.19])
    p_free = mass @ v + dt * np.linspace(-1, 1, n)
    tau, torque = implicit_friction_force(
        jl,
        jt,
        np.zeros(n),
        mass,
        p_free,
        v,
        dt,
        normal_force=normal,
        eps=eps,
        newton_steps=8,
        servo=(offset, rate, power),
        **PAPER,
    )
    v_next = np.linalg.solve(mass, p_free + dt * (tau + torque))
    assert np.allclose(torque, np.clip(offset - rate * v_next, -power, power), rtol=1e-9, atol=1e-12)
    assert torque[4] == 1.19 and np.all(np.abs(torque[2:4]) < 1.19) and torque[5] != 0.0
    f_long, f_lat = wheel_friction_forces(jl @ v_next, jt @ v_next, normal_force=normal, eps=eps, **PAPER)
    assert np.allclose(tau, jl.T @ f_long + jt.T @ f_lat, rtol=1e-8, atol=1e-9)


def test_implicit_step_tends_to_the_explicit_law_for_small_steps():
    mass, jl, jt, v = _random_problem(3)
    v = v * 20  # sliding well outside the smoothing zone
    normal = np.full(len(jl), N)
    dt = 1e-9
    tau = implicit_friction_force(
        jl, jt, np.zeros(len(v)), mass, mass @ v, v, dt, normal_force=normal, eps=1e-3, newton_steps=2, **PAPER
    )
    f_long, f_lat = wheel_friction_forces(jl @ v, jt @ v, normal_force=normal, eps=1e-3, **PAPER)
    assert np.allclose(tau, jl.T @ f_long + jt.T @ f_lat, rtol=1e-5)


def test_implicit_friction_dissipates_and_is_bounded():
    mass, jl, jt, v = _random_problem(4)
    normal = np.full(len(jl), N)
    for dt in (1e-4, 1e-3, 1e-2):
        tau = implicit_friction_force(
            jl, jt, np.zeros(len(v)), mass, mass @ v, v, dt, normal_force=normal, eps=1e-3, newton_steps=4, **PAPER
        )
        v_next = v + dt * np.linalg.solve(mass, tau)
        assert v_next @ mass @ v_next < v @ mass @ v  # kinetic energy falls
        assert tau @ v_next < 0  # friction does negative work


def test_implicit_step_converges_with_stiff_servos_at_their_clamp():
    """The replay's servos (Kd + dt Kp = 1.3 N m s/rad, 3 N m) on light modules at 1 ms, commands spread across
    the clamp: a plain Newton step cycles where the clamp switches (two steps, as before: 195 of 200 such
    problems missed backward Euler, by up to 5 N m; the replays chattered). The damped solve meets it on all."""
    n, w, dt = 16, 13, 1e-3
    rate, power = np.r_[np.zeros(3), np.full(13, 1.3)], np.r_[np.zeros(3), np.full(13, 3.0)]
    for seed in range(40):
        rng = np.random.default_rng(seed)
        a = rng.normal(size=(n, n))
        mass = 1e-3 * (a @ a.T + n * np.eye(n)) + np.diag(np.r_[np.full(3, 4.0), np.zeros(13)])
        jl, jt = 0.1 * rng.normal(size=(w, n)), 0.1 * rng.normal(size=(w, n))
        v = rng.normal(scale=0.3, size=n)
        offset = np.r_[np.zeros(3), rng.normal(scale=3.0, size=13) + 1.3 * v[3:]]
        p_free = mass @ v + dt * rng.normal(size=n)
        tau, torque = implicit_friction_force(
            jl,
            jt,
            np.zeros(n),
            mass,
            p_free,
            v,
            dt,
            normal_force=np.full(w, N),
            eps=1e-3,
            newton_steps=20,
            servo=(offset, rate, power),
            **PAPER,
        )
        v_next = np.linalg.solve(mass, p_free + dt * (tau + torque))
        assert np.allclose(torque, np.clip(offset - rate * v_next, -power, power), rtol=0, atol=1e-8), seed
        f_long, f_lat = wheel_friction_forces(jl @ v_next, jt @ v_next, normal_force=np.full(w, N), eps=1e-3, **PAPER)
        assert np.allclose(tau, jl.T @ f_long + jt.T @ f_lat, rtol=0, atol=1e-8), seed


def test_the_steps_hand_lu_solves_as_lapack_does_and_gives_nan_where_there_is_no_solution():
    """The unsymmetric step's solve (a discrepancy term's side force): partial pivoting by hand, against LAPACK on a
    matrix whose first pivot is 0 (it must pivot), and NaN, not an exception, for a singular or non-finite one."""
    from rc1_drake.friction import lu_factor, lu_factor_solve, lu_solve

    rng = np.random.default_rng(3)
    matrix = rng.normal(size=(16, 16))
    matrix[0, 0] = 0.0
    rhs = rng.normal(size=16)
    np.testing.assert_allclose(lu_solve(matrix, rhs), np.linalg.solve(matrix, rhs), rtol=1e-10, atol=1e-12)
    factors, order = lu_factor(matrix)
    other = rng.normal(size=16)
    np.testing.assert_allclose(lu_factor_solve(factors, order, other), np.linalg.solve(matrix, other), rtol=1e-10,
                               atol=1e-12)  # fmt: skip
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    assert np.isnan(lu_solve(singular, np.ones(2))).all()
    assert np.isnan(lu_solve(np.full((2, 2), np.inf), np.ones(2))).all()
