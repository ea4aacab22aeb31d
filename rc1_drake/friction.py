"""Friction: the wheels' (paper Eqs. 4-5) and a failed joint's (section 3), as numpy kernels and one
LeafSystem that solves them implicitly.

Each wheel (modules 2-14; the head has none) feels, in its own frame (+x rolling direction, +y lateral),

    F_lat  = -sgn(v_lat)  (c_lat  |v_lat|  + mu_lat  N)        (Eq. 4)
    F_long = -sgn(v_long) (c_long |v_long| + mu_long N)        (Eq. 5)

with N = m g, the weight of the wheel's module. The paper writes the magnitudes with sgn(v); the minus
sign makes the force oppose the wheel's velocity. sgn(v) c |v| = c v exactly, so only the Coulomb
term needs a sign: we use the smooth sign v / sqrt(v^2 + eps^2), equal to sgn(v) for |v| >> eps.

Why the friction is implicit. With the sign smoothed, the Coulomb term is a damper of rate mu N / eps
near v = 0: 4.2 N / 1 mm/s on a 0.29 kg module, a time constant of 0.07 ms. An explicit step must be
shorter still, and a larger eps changes the answer (a joint-7 failure drifts 25 cm less at eps =
10 mm/s than at 1 mm/s). So the system solves the backward-Euler step of Eqs. 4-5 itself:

    M v+ = M v + dt (tau_servo - C(q, v) v) + dt J^T f(J v+)

for the velocity v+ at the end of the step (J: wheel velocity Jacobians), and outputs the force that
produces it, tau = J^T f(J v+) = (M v+ - p_free) / dt. It starts from the secant linearisation
f(u) ~ -D(u_n) u with D = c + mu N / sqrt(u_n^2 + eps^2) and polishes with Newton steps, each backtracked
until the residual falls, until they move no velocity by 1e-7 m/s (tests/test_friction.py). The plant's
own step then reproduces v+ up to what this prediction leaves out: the joint-limit impulses, which
the plant itself treats implicitly. A failed joint's viscous friction -c_joint q_dot is in the same
solve, so all five of the paper's friction coefficients are parameters of this one system.
tests/test_convergence.py shows that halving eps or the time step moves the result by less than 1%
of the distance travelled.
"""

from __future__ import annotations

import collections
import dataclasses

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem, ValueProducer

from .articulated import add_point_rate, articulated_matrix, articulated_solve, chain_inertias
from .config import GRAVITY_M_S2, NUM_JOINTS, Friction
from .discrepancy import NJK, NSK, NUM_SITES, NUM_TERMS, site_arrays, site_coefficients, site_force
from .kinematics import ChainGeometry, chain_frames, jit, wheel_kinematics_at, wheel_kinematics_kernel
from .model import module_inertias, set_payload


@jit
def smooth_sign(v, eps):
    """sgn(v) for eps = 0, else v / sqrt(v^2 + eps^2)."""
    if eps == 0.0:
        return np.sign(v)
    return v / np.sqrt(v * v + eps * eps)


# Shape of the Coulomb terms beyond the paper (rc1_drake/effects/); zeros give Eqs. 4-5 exactly:
# [lateral asymmetry a_lat, longitudinal asymmetry a_long, Stribeck ratio r, Stribeck speed v_s (m/s)].
PAPER_SHAPE = np.array([0.0, 0.0, 0.0, 0.01])


@jit
def coulomb_law(u, mu_n, eps, asymmetry, ratio, speed, clip=True):
    """The Coulomb term mu N (1 + a sgn(u)) (1 + r exp(-(u/v_s)^2)) sgn(u) of one slip speed u, and the secant
    and tangent rates of the whole friction law f(u) = -(c u + that): f = -secant u, df/du = -tangent (before
    adding c).

    a != 0 makes sliding toward +u resist more than toward -u (mu N (1 + a) against mu N (1 - a));
    r > 0 adds breakaway friction that fades above the Stribeck speed v_s. The tangent is clipped at 0
    (a Stribeck law falls with speed) so that the implicit solve's matrix stays positive definite; `clip=False`
    gives the exact derivative (the solve's sensitivities, engine/tangent.py)."""
    root = np.sqrt(u * u + eps * eps)
    s = u / root
    ds = eps * eps / (root * root * root)
    decay = np.exp(-((u / speed) ** 2)) if ratio != 0.0 else 0.0
    magnitude = mu_n * (1.0 + asymmetry * s) * (1.0 + ratio * decay)
    slope = mu_n * (asymmetry * ds * (1.0 + ratio * decay) - (1.0 + asymmetry * s) * ratio * decay * 2.0 * u / speed**2)
    tangent = slope * s + magnitude * ds
    return magnitude * s, magnitude / root, max(tangent, 0.0) if clip else tangent


@jit
def _coulomb(u, mu_n, eps, asymmetry, ratio, speed):
    """coulomb_law over arrays u and mu_n: (force, secant, tangent) arrays."""
    force, secant, tangent = np.empty(u.shape[0]), np.empty(u.shape[0]), np.empty(u.shape[0])
    for i in range(u.shape[0]):
        force[i], secant[i], tangent[i] = coulomb_law(u[i], mu_n[i], eps, asymmetry, ratio, speed)
    return force, secant, tangent


@jit
def _wheel_coulomb(v_long, v_lat, mu_long, mu_lat, normal_force, eps, shape):
    """_coulomb's (force, secant, tangent) along the wheels and across them; shape = [lateral asymmetry,
    longitudinal asymmetry, Stribeck ratio, Stribeck speed] (the Stribeck terms act laterally only)."""
    return (
        _coulomb(v_long, mu_long * normal_force, eps, shape[1], 0.0, shape[3]),
        _coulomb(v_lat, mu_lat * normal_force, eps, shape[0], shape[2], shape[3]),
    )


@jit
def _wheel_forces(v_long, v_lat, mu_long, mu_lat, c_long, c_lat, normal_force, eps, shape):
    if eps == 0.0:  # the exact sign: the paper's law (shape terms need eps > 0)
        return (
            -(c_long * v_long + mu_long * normal_force * np.sign(v_long)),
            -(c_lat * v_lat + mu_lat * normal_force * np.sign(v_lat)),
        )
    along, across = _wheel_coulomb(v_long, v_lat, mu_long, mu_lat, normal_force, eps, shape)
    return -(c_long * v_long + along[0]), -(c_lat * v_lat + across[0])


def wheel_friction_forces(
    v_long,
    v_lat,
    mu_long,
    mu_lat,
    c_long,
    c_lat,
    normal_force,
    eps,
    *,
    lat_asymmetry=0.0,
    long_asymmetry=0.0,
    stribeck_ratio=0.0,
    stribeck_speed_m_s=0.01,
):
    """Longitudinal and lateral friction force on each wheel, in the wheel's frame (Eqs. 4-5).

    v_long, v_lat: the wheel centre's velocity along its rolling and lateral axes (m/s);
    normal_force: N per wheel (newtons); eps: sgn() smoothing (m/s). Returns (f_long, f_lat), N.
    The keyword terms are candidate effects (rc1_drake/effects/; 0 is the paper's model): the Coulomb part
    becomes mu N (1 + a sgn(v)) sgn(v), and laterally also (1 + r exp(-(v/v_s)^2)) (Stribeck).
    """
    shape = np.array([lat_asymmetry, long_asymmetry, stribeck_ratio, stribeck_speed_m_s], dtype=float)
    return _wheel_forces(
        np.asarray(v_long, dtype=float),
        np.asarray(v_lat, dtype=float),
        mu_long,
        mu_lat,
        c_long,
        c_lat,
        np.asarray(normal_force, dtype=float),
        eps,
        shape,
    )


@jit
def cholesky(matrix):
    """The lower Cholesky factor of a symmetric matrix, or an empty array if it is not positive definite.
    The step's matrices are 16 x 16: a hand loop beats LAPACK's call overhead several times."""
    n = matrix.shape[0]
    low = np.zeros((n, n))
    for j in range(n):
        pivot = matrix[j, j]
        for k in range(j):
            pivot -= low[j, k] * low[j, k]
        if not pivot > 0.0:
            return np.zeros((0, 0))
        root = np.sqrt(pivot)
        low[j, j] = root
        for i in range(j + 1, n):
            value = matrix[i, j]
            for k in range(j):
                value -= low[i, k] * low[j, k]
            low[i, j] = value / root
    return low


@jit
def cholesky_solve(low, rhs):
    """matrix^-1 rhs from matrix's lower Cholesky factor."""
    n = low.shape[0]
    out = rhs.copy()
    for i in range(n):
        for k in range(i):
            out[i] -= low[i, k] * out[k]
        out[i] /= low[i, i]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            out[i] -= low[k, i] * out[k]
        out[i] /= low[i, i]
    return out


@jit
def spd_solve(matrix, rhs):
    """matrix^-1 rhs for a symmetric positive definite matrix, by Cholesky (LU if it is not definite)."""
    low = cholesky(matrix)
    if low.shape[0] == 0:
        return lu_solve(matrix, rhs)
    return cholesky_solve(low, rhs)


@jit
def lu_factor(matrix):
    """(the LU factors of `matrix` in one array, the row order) by partial pivoting, by hand as cholesky (16 x 16:
    LAPACK's call costs more); an empty array where the matrix is not finite or singular (a run that blew up: the
    engine then stops it with an error, where LAPACK's exception from compiled code can corrupt the heap)."""
    n = matrix.shape[0]
    order = np.arange(n)
    if not np.isfinite(matrix).all():
        return np.zeros((0, 0)), order
    a = matrix.copy()
    for k in range(n):
        pivot = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[pivot, k]):
                pivot = i
        if a[pivot, k] == 0.0:
            return np.zeros((0, 0)), order
        if pivot != k:
            for j in range(n):
                a[k, j], a[pivot, j] = a[pivot, j], a[k, j]
            order[k], order[pivot] = order[pivot], order[k]
        for i in range(k + 1, n):
            a[i, k] /= a[k, k]
            for j in range(k + 1, n):
                a[i, j] -= a[i, k] * a[k, j]
    return a, order


@jit
def lu_factor_solve(factors, order, rhs):
    """matrix^-1 rhs from lu_factor's (factors, order); NaN where it found none."""
    n = rhs.shape[0]
    if factors.shape[0] == 0:
        return np.full(n, np.nan)
    out = rhs[order].astype(np.float64)
    for i in range(n):
        for k in range(i):
            out[i] -= factors[i, k] * out[k]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            out[i] -= factors[i, k] * out[k]
        out[i] /= factors[i, i]
    return out


@jit
def lu_solve(matrix, rhs):
    """matrix^-1 rhs by LU (lu_factor); NaN where the matrix is not finite or singular."""
    factors, order = lu_factor(matrix)
    return lu_factor_solve(factors, order, rhs)


@jit
def _step_solve(matrix, rhs, symmetric):
    """matrix^-1 rhs: spd_solve, or LU for a step matrix that is not symmetric."""
    return spd_solve(matrix, rhs) if symmetric else lu_solve(matrix, rhs)


@jit
def _isotropic(u_xy, coulomb, eps):
    """Isotropic Coulomb friction -C u / sqrt(|u|^2 + eps^2) of a point sliding at u_xy (2,): the force,
    its secant rate (scalar) and its tangent matrix (2x2, positive semidefinite)."""
    root = np.sqrt(u_xy[0] ** 2 + u_xy[1] ** 2 + eps * eps)
    tangent = coulomb / root * (np.eye(2) - np.outer(u_xy, u_xy) / (root * root))
    return -coulomb * u_xy / root, coulomb / root, tangent


@jit
def _servo_torque(offset, rate, power, v_next):
    """The servos' backward-Euler torque clamp(offset - rate v+, +-power) and which servos are not saturated."""
    torque, linear = np.empty(offset.shape[0]), np.empty(offset.shape[0])
    for a in range(offset.shape[0]):  # a loop: the array expression allocates five temporaries, twice a step
        raw = offset[a] - rate[a] * v_next[a]
        torque[a] = min(max(raw, -power[a]), power[a])
        linear[a] = 1.0 if abs(raw) < power[a] else 0.0
    return torque, linear


@jit
def jacobian_span(jac_long, jac_lat, w):
    """How many leading coordinates move wheel w (its Jacobian rows are zero beyond them)."""
    span = jac_long.shape[1]
    while span > 0 and jac_long[w, span - 1] == 0.0 and jac_lat[w, span - 1] == 0.0:
        span -= 1
    return span


# One step's friction laws and servos, as step_rates takes them (friction_problem builds them): a new force term
# enters here, in friction_problem and in step_rates (its rate's place in assemble_step and step_system, its
# derivative in engine/tangent.py), and nowhere else. The functions the Newton loop calls are inlined (numba's
# inline="always"), and the ones it calls most take the arrays they read, not the tuple: passing the tuple, inlined
# or not, counts a reference on each of its ~20 arrays at every call, several times a step.
StepLaws = collections.namedtuple(
    "StepLaws",
    [
        "jac_long",  # (W, nv) wheel velocity Jacobians along and across the wheels
        "jac_lat",
        "spans",  # (W,) how many leading coordinates move each wheel
        "mass_damped",  # M + dt diag(joint damping)
        "dt",
        "mu_long",
        "mu_lat",
        "c_long",
        "c_lat",
        "normal_force",  # (W,)
        "eps",  # the sgn() smoothing, m/s
        "shape",  # PAPER_SHAPE's layout: asymmetries, Stribeck ratio and speed
        "jac_drag",  # (2P, nv) the velocity Jacobians of P points with an isotropic Coulomb drag: head, tail's end
        "drag_coulomb",  # (P,) N: the head's skid (effects.HeadDrag), the tether's pull (effects.TailTether)
        "drag_eps",  # (P,) their sgn() smoothing, m/s
        "joint_coulomb",  # (nv,) failed joints' dry friction, N m, its sign smoothed at joint_eps rad/s
        "joint_eps",
        "servo_offset",  # (nv,) the servos' backward-Euler torque clamp(offset - rate v+, +-power)
        "servo_rate",
        "servo_power",
        # (S, 2 nv + NSK) per discrepancy site (discrepancy.py): its velocity Jacobian along its module, across it,
        # and its coefficients, in one array (a field per part costs every call its reference counts); S = 0 when
        # the model has no term. Its failed-joint terms are in joint_coulomb, mass_damped and the known torque.
        "sites",
        # The same matrix body by body (articulated.py), for the O(n) solve: each module's planar inertia (nm, 3, 3)
        # and each joint's motion (nj, 3) at the step's start, and the joints' own rate dt (damping + a stop's rate)
        # (nv,). No modules (an empty inertia): the solve is dense.
        "inertia",
        "motion",
        "joint_rate",
    ],
)


@jit(inline="always")
def step_rates(v_next, tangent, laws, exact=False):
    """The step's generalized force f(v+) but the discrepancy's (wheels, head and tail drags, joint Coulomb, servos;
    Eqs. 4-5) and dt times the rate of -f term by term: each wheel's along and across its rolling direction (W, 2),
    each drag point's (P, 2, 2) and the joints' own (nv,); the rate is the tangent (Newton) if `tangent`, else the
    secant (the start, which linearizes each Coulomb term through the origin); `exact`: the tangent unclipped
    (coulomb_law). Also returns which servos are not saturated."""
    (jac_long, jac_lat, spans, _, dt, mu_long, mu_lat, c_long, c_lat, normal_force, eps, shape, jac_drag,
     drag_coulomb, drag_eps, joint_coulomb, joint_eps, servo_offset, servo_rate, servo_power,
     _, _, _, _) = laws  # fmt: skip
    n = v_next.shape[0]
    force = np.zeros(n)
    wheel = np.empty((jac_long.shape[0], 2))
    for w in range(jac_long.shape[0]):
        span = spans[w]
        u_long, u_lat = 0.0, 0.0
        for a in range(span):
            u_long += jac_long[w, a] * v_next[a]
            u_lat += jac_lat[w, a] * v_next[a]
        c_l, s_l, t_l = coulomb_law(u_long, mu_long * normal_force[w], eps, shape[1], 0.0, shape[3], not exact)
        c_t, s_t, t_t = coulomb_law(u_lat, mu_lat * normal_force[w], eps, shape[0], shape[2], shape[3], not exact)
        f_long, f_lat = -(c_long * u_long + c_l), -(c_lat * u_lat + c_t)
        wheel[w, 0] = dt * (c_long + (t_l if tangent else s_l))
        wheel[w, 1] = dt * (c_lat + (t_t if tangent else s_t))
        for a in range(span):
            force[a] += jac_long[w, a] * f_long + jac_lat[w, a] * f_lat
    joint = np.zeros(n)
    linear = np.zeros(n)
    for a in range(n):
        if joint_coulomb[a] != 0.0:  # a discrepancy's dry torque may take some away
            f_j, s_j, t_j = coulomb_law(v_next[a], joint_coulomb[a], joint_eps, 0.0, 0.0, 1.0, not exact)
            force[a] -= f_j
            joint[a] += dt * (t_j if tangent else s_j)
        raw = servo_offset[a] - servo_rate[a] * v_next[a]
        force[a] += min(max(raw, -servo_power[a]), servo_power[a])
        if abs(raw) < servo_power[a]:
            linear[a] = 1.0
            joint[a] += dt * servo_rate[a]
    drag = np.zeros((drag_coulomb.shape[0], 2, 2))
    for p in range(drag_coulomb.shape[0]):
        if drag_coulomb[p] > 0.0:
            jac = np.ascontiguousarray(jac_drag[2 * p : 2 * p + 2])
            f_p, secant, k_p = _isotropic(jac @ v_next, drag_coulomb[p], drag_eps[p])
            force += jac.T @ f_p
            drag[p] = dt * k_p if tangent else dt * secant * np.eye(2)
    return force, wheel, joint, drag, linear


@jit
def assemble_step(v_next, tangent, laws, exact=False):
    """The step's generalized force f(v+) (wheels, head, joint Coulomb, servos, the discrepancy; Eqs. 4-5) and the
    matrix mass_damped + dt * (rate of -f), dense (step_rates for `tangent` and `exact`). Also returns which servos
    are not saturated."""
    force, wheel, joint, drag, linear = step_rates(v_next, tangent, laws, exact)
    jac_long, jac_lat, spans, mass_damped, dt, jac_drag, sites = (
        laws.jac_long, laws.jac_lat, laws.spans, laws.mass_damped, laws.dt, laws.jac_drag, laws.sites
    )  # fmt: skip
    n = v_next.shape[0]
    matrix = mass_damped.copy()
    for w in range(jac_long.shape[0]):
        for a in range(spans[w]):
            la, ta = wheel[w, 0] * jac_long[w, a], wheel[w, 1] * jac_lat[w, a]
            for b in range(a + 1):
                matrix[a, b] += la * jac_long[w, b] + ta * jac_lat[w, b]
    for a in range(n):
        matrix[a, a] += joint[a]
    for a in range(n):
        for b in range(a):
            matrix[b, a] = matrix[a, b] - mass_damped[a, b] + mass_damped[b, a]
    for p in range(drag.shape[0]):
        if laws.drag_coulomb[p] > 0.0:
            jac = np.ascontiguousarray(jac_drag[2 * p : 2 * p + 2])
            matrix += jac.T @ np.ascontiguousarray(drag[p]) @ jac
    # The discrepancy model (discrepancy.py), by its exact rate in both modes: its terms are small beside Eqs. 4-5.
    for s in range(sites.shape[0]):
        along_s, across_s = sites[s, :n], sites[s, n : 2 * n]
        span = n  # a site moves with the coordinates up to its module's joint only
        while span > 0 and along_s[span - 1] == 0.0 and across_s[span - 1] == 0.0:
            span -= 1
        u_long, u_lat = 0.0, 0.0
        for a in range(span):  # loops, not BLAS calls: a step makes ~90 of these
            u_long += along_s[a] * v_next[a]
            u_lat += across_s[a] * v_next[a]
        f_s, rate = site_force(u_long, u_lat, sites[s, 2 * n :], laws.eps)
        for a in range(span):
            force[a] += along_s[a] * f_s[0] + across_s[a] * f_s[1]
            along = rate[0, 0] * along_s[a] + rate[1, 0] * across_s[a]
            across = rate[0, 1] * along_s[a] + rate[1, 1] * across_s[a]
            for b in range(span):
                matrix[a, b] -= dt * (along * along_s[b] + across * across_s[b])
    return force, matrix, linear


@jit(inline="always")
def step_system(v_next, tangent, laws):
    """(f(v+), the step matrix as the solve takes it, which servos are not saturated): body by body (articulated.py)
    where the laws carry the modules' inertias and no discrepancy site (its side force is not symmetric), else
    dense (assemble_step). The matrix is (dense, modules' inertias with the rates or empty, joint rates); where the
    inertias are given, the dense part is M + dt diag(damping) unchanged and system_solve does not read it."""
    if laws.inertia.shape[0] == 0 or laws.sites.shape[0] > 0:
        force, matrix, linear = assemble_step(v_next, tangent, laws)
        return force, (matrix, np.zeros((0, 3, 3)), np.zeros(0)), linear
    force, wheel, joint, drag, linear = step_rates(v_next, tangent, laws)
    inertia = laws.inertia.copy()
    # Each field read once, not in the loops: a field of the tuple read is an array's reference count taken
    jac_long, jac_lat, jac_drag, spans, drag_coulomb, joint_rate = (
        laws.jac_long, laws.jac_lat, laws.jac_drag, laws.spans, laws.drag_coulomb, laws.joint_rate
    )  # fmt: skip
    # A point's P^T D P on the last module whose joint moves it (P: its rows' twist part, articulated.py); behind a
    # joint that does not move it, it may as well ride ahead of that joint.
    for w in range(jac_long.shape[0]):
        k = max(spans[w] - 3, 0)
        for a in range(3):
            la, ta = wheel[w, 0] * jac_long[w, a], wheel[w, 1] * jac_lat[w, a]
            for b in range(3):
                inertia[k, a, b] += la * jac_long[w, b] + ta * jac_lat[w, b]
    for p in range(drag.shape[0]):
        if drag_coulomb[p] > 0.0:
            span = max(jacobian_span(jac_drag, jac_drag, 2 * p), jacobian_span(jac_drag, jac_drag, 2 * p + 1))
            add_point_rate(inertia[max(span - 3, 0)], jac_drag[2 * p : 2 * p + 2, :3], drag[p])
    for a in range(joint.shape[0]):
        joint[a] += joint_rate[a]  # in place: the joints' own rate and the friction's (step_rates' array)
    return force, (laws.mass_damped, inertia, joint), linear  # unread dense part: no allocation


@jit(inline="always")
def system_solve(system, motion, symmetric, rhs):
    """system^-1 rhs for step_system's matrix: by the articulated-body recursion (the joints' `motion`), or densely
    (Cholesky where `symmetric`, LU where the matrix is not definite or not symmetric)."""
    dense, inertia, joint_rate = system
    if inertia.shape[0] == 0:
        return _step_solve(dense, rhs, symmetric)
    out = articulated_solve(inertia, joint_rate, motion, rhs)
    if out.shape[0] == 0:
        return lu_solve(articulated_matrix(inertia, joint_rate, motion), rhs)
    return out


@jit
def _step_residual(v_next, force, mass_damped, dt, momentum_free):
    """The backward-Euler step's residual M v+ - p_free - dt f(v+) (with c_joint in M), f(v+) = `force`."""
    n = v_next.shape[0]
    residual = np.empty(n)
    for a in range(n):  # loops, not a BLAS call and temporaries: this runs ~4 times a step on a 16 x 16
        total = 0.0
        for b in range(n):
            total += mass_damped[a, b] * v_next[b]
        residual[a] = total - momentum_free[a] - dt * force[a]
    return residual


# A Newton step under 10 um/s ends the solve once taken: the error left is ~step^2 / eps (measured on a replay:
# 130-1200 step^2, so <= ~1e-7 m/s, 1e-4 of the sgn() smoothing), and a quarter of a step's cost is saved. A run
# that is differentiated solves on (engine/tangent.py linearizes the converged step: at 1e-5 its columns miss
# central differences by 3e-4).
NEWTON_FINAL_STEP_M_S = 1e-5
TANGENT_FINAL_STEP_M_S = 1e-7
NEWTON_STALL_M_S = 1e-9  # a backtracked step that moves no velocity by this much: the line search has stalled
MAX_HALVINGS = 12


@jit
def _largest_magnitude(a):
    """max |a_i|, without np.abs's temporary."""
    out = 0.0
    for x in a:
        out = max(out, abs(x))
    return out


@jit
def _implicit_friction_force(laws, mass_matrix, momentum_free, v, newton_steps, final_step):
    dt, servo_offset, servo_rate, servo_power = laws.dt, laws.servo_offset, laws.servo_rate, laws.servo_power
    motion, symmetric, mass_damped = laws.motion, laws.sites.shape[0] == 0, laws.mass_damped
    # The secant start: each Coulomb term through the origin at its rate at v; the servos as they stand at
    # v, linear where not saturated, a constant torque where saturated.
    _, system, linear = step_system(v, False, laws)
    servo = _servo_torque(servo_offset, servo_rate, servo_power, v)[0]
    rhs = np.empty(v.shape[0])
    for a in range(v.shape[0]):
        rhs[a] = momentum_free[a] + dt * (linear[a] * servo_offset[a] + (1.0 - linear[a]) * servo[a])
    v_next = system_solve(system, motion, symmetric, rhs)
    # Newton steps from that secant start, each backtracked until the residual's norm falls (Armijo): a plain
    # Newton step cycles where the servo clamp or a Coulomb kink switches within the step, and the servos then
    # chatter (seen at 1 ms on noisy measured angles with two undamped steps).
    force, system, _ = step_system(v_next, True, laws)
    residual = _step_residual(v_next, force, mass_damped, dt, momentum_free)
    for _ in range(newton_steps):
        step = system_solve(system, motion, symmetric, residual)
        largest = _largest_magnitude(step)
        if largest < final_step:  # converged: take the last step, nothing left to check
            v_next = v_next - step
            break
        norm = residual @ residual
        alpha = 1.0
        for _ in range(MAX_HALVINGS):
            trial = np.empty_like(v_next)
            for a in range(trial.shape[0]):
                trial[a] = v_next[a] - alpha * step[a]
            force, trial_system, _ = step_system(trial, True, laws)
            trial_residual = _step_residual(trial, force, mass_damped, dt, momentum_free)
            if trial_residual @ trial_residual <= (1.0 - 1e-4 * alpha) * norm:
                break
            alpha *= 0.5
        moved = alpha * largest
        v_next, residual, system = trial, trial_residual, trial_system
        if moved < NEWTON_STALL_M_S:
            break
    servo = _servo_torque(servo_offset, servo_rate, servo_power, v_next)[0]
    # The plant applies the servo torque itself; v+ also returned: the plant's free motion, without a second solve.
    force = mass_matrix @ v_next
    for a in range(force.shape[0]):
        force[a] = (force[a] - momentum_free[a]) / dt - servo[a]
    return force, servo, v_next


def implicit_friction_force(
    jac_long,
    jac_lat,
    joint_damping,
    mass_matrix,
    momentum_free,
    v,
    dt,
    mu_long,
    mu_lat,
    c_long,
    c_lat,
    normal_force,
    eps,
    newton_steps,
    *,
    shape=PAPER_SHAPE,
    jac_head=None,
    head_coulomb=0.0,
    joint_coulomb=None,
    joint_eps=0.01,
    servo=None,
):
    """Generalized friction force of one backward-Euler step (module docstring).

    jac_long, jac_lat: (W, nv) wheel velocity Jacobians along the rolling and lateral axes;
    joint_damping: (nv,) viscous joint friction per coordinate (c_joint on failed joints, else 0);
    momentum_free: M v + dt * (every other generalized force); v: the velocity at the step's start.
    eps must be > 0: the implicit solve needs a finite damping rate at v = 0. Candidate effects
    (rc1_drake/effects/; defaults are the paper's model): `shape` (PAPER_SHAPE's layout), an isotropic
    Coulomb drag `head_coulomb` (N) on the point whose (2, nv) velocity Jacobian is `jac_head`, and
    dry joint friction `joint_coulomb` (nv,) in N m, its sign smoothed at `joint_eps` rad/s.
    `servo` = (offset, rate, power), each (nv,): servos in the same step, with torque
    clamp(offset - rate v+, +-power) (FrictionForces' backward-Euler PID); then returns (force, servo torque).
    """
    nv = len(v)
    offset, rate, power = (np.zeros(nv),) * 3 if servo is None else (np.asarray(s, dtype=float) for s in servo)
    jac_long, jac_lat = np.ascontiguousarray(jac_long, dtype=float), np.ascontiguousarray(jac_lat, dtype=float)
    laws = StepLaws(
        jac_long,
        jac_lat,
        np.array([jacobian_span(jac_long, jac_lat, w) for w in range(jac_long.shape[0])]),
        mass_matrix + dt * np.diag(joint_damping),
        float(dt),
        float(mu_long),
        float(mu_lat),
        float(c_long),
        float(c_lat),
        np.asarray(normal_force, dtype=float),
        float(eps),
        np.asarray(shape, dtype=float),
        np.zeros((2, nv)) if jac_head is None else np.ascontiguousarray(jac_head, dtype=float),
        np.array([float(head_coulomb)]),
        np.array([float(eps)]),
        np.zeros(nv) if joint_coulomb is None else np.asarray(joint_coulomb, dtype=float),
        float(joint_eps),
        offset,
        rate,
        power,
        np.zeros((0, nv)),
        np.zeros((0, 3, 3)),
        np.zeros((0, 3)),
        dt * np.asarray(joint_damping, dtype=float),
    )
    force, torque, _ = _implicit_friction_force(
        laws, mass_matrix, momentum_free, v, newton_steps, TANGENT_FINAL_STEP_M_S
    )
    return force if servo is None else (force, torque)


# Parameter layout of FrictionForces: the paper's five coefficients, eps; the effect terms (rc1_drake/effects/:
# PAPER_SHAPE's four, the head's Coulomb drag coefficient and normal force, dry friction of a failed
# joint, a payload's mass and module, a failed joint's compliant stop: stiffness, damping, onset angle); then per
# joint its state (0 working, 1 failed free: its
# friction acts, 2 locked: the plant holds it, and the solve predicts so), then per wheel its normal
# force, then per wheel its toe angle (rad, counter-clockwise, added to the SDF's wheel yaw).
C_JOINT, MU_LAT, MU_LONG, C_LAT, C_LONG, EPS = range(6)
SHAPE = slice(6, 10)
HEAD_MU, HEAD_NORMAL, JOINT_COULOMB, PAYLOAD_KG, PAYLOAD_MODULE, STOP_K, STOP_D, STOP_ONSET, TETHER_N = range(10, 19)
SCALARS = 19
TETHER_EPS_M_S = 0.05  # the tether's sgn() smoothing: a cable's drag builds up over a few cm/s
WORKING, FREE, LOCKED = 0.0, 1.0, 2.0
LOCKED_DAMPING = 1e4  # N m s/rad: in the prediction only, a locked joint barely moves
JOINT_EPS_RAD_S = 0.01  # sgn() smoothing of a failed joint's dry friction
FAILED = slice(SCALARS, SCALARS + NUM_JOINTS)
PER_WHEEL = SCALARS + NUM_JOINTS


def friction_parameters(*, friction: Friction, sgn_smoothing_m_s: float, setup, geometry: ChainGeometry) -> np.ndarray:
    """The parameter vector (layout above) of a run: the five coefficients, eps, the terms of the effects
    gathered in `setup` (effects.ModelSetup), every joint working, each wheel's normal force (its module's
    weight on the floor, m g cos(slope), payload included) and toe. Both engines take it from here."""
    if not sgn_smoothing_m_s > 0:
        raise ValueError("the implicit friction needs sgn_smoothing_m_s > 0")
    nw = len(geometry.wheel_module)
    if nw != NUM_SITES - 2:
        raise ValueError(f"the discrepancy model's sites expect {NUM_SITES - 2} wheels, the geometry has {nw}")
    params = np.zeros(PER_WHEEL + 2 * nw + NUM_TERMS)
    params[: EPS + 1] = FrictionForces.pack(friction, sgn_smoothing_m_s)
    params[SHAPE] = [
        setup.lateral_asymmetry,
        setup.longitudinal_asymmetry,
        setup.stribeck_ratio,
        setup.stribeck_speed_m_s,
    ]
    params[HEAD_MU] = setup.head_mu
    params[JOINT_COULOMB] = setup.joint_coulomb_Nm
    params[PAYLOAD_KG], params[PAYLOAD_MODULE] = setup.payload_kg, setup.payload_module
    params[STOP_K], params[STOP_D], params[STOP_ONSET] = setup.stop_k, setup.stop_d, setup.stop_onset_rad
    params[TETHER_N] = setup.tail_tether_N
    weight = np.array(geometry.module_mass, dtype=float)
    if setup.payload_module:
        weight[setup.payload_module - 1] += setup.payload_kg
    weight *= -setup.gravity[2]
    params[HEAD_NORMAL] = weight[0]
    carried = np.zeros_like(weight)  # a cantilevered head's weight on wheels 2 and 3 (effects.HeadCantilever)
    carried[1], carried[2] = setup.head_on_wheel2, -max(setup.head_on_wheel2 - 1.0, 0.0)
    params[normal_slice(nw)] = (weight + carried * weight[0])[geometry.wheel_module]
    params[toe_slice(nw)] = setup.wheel_toe_rad
    params[discrepancy_slice(nw)] = setup.discrepancy
    return params


def normal_slice(num_wheels: int) -> slice:
    return slice(PER_WHEEL, PER_WHEEL + num_wheels)


def toe_slice(num_wheels: int) -> slice:
    return slice(PER_WHEEL + num_wheels, PER_WHEEL + 2 * num_wheels)


def discrepancy_slice(num_wheels: int) -> slice:
    """The discrepancy model's coefficients (discrepancy.term_names' order), after the toes."""
    return slice(PER_WHEEL + 2 * num_wheels, PER_WHEEL + 2 * num_wheels + NUM_TERMS)


@jit
def tail_end_jacobian(x, chain):
    """(2, nv): the world x and y velocity of the tail's end (its front joint mirrored through its centre) per unit
    rate of each coordinate, where a tether pulls (effects.TailTether)."""
    joint_in_parent, joint_in_child, _, _, _ = chain
    tail = np.array([joint_in_parent.shape[0]])
    _, _, jacobian = wheel_kinematics_kernel(
        x, joint_in_parent, joint_in_child, tail, -joint_in_child[-1:], np.ones(1, dtype=np.complex128)
    )
    out = np.empty((2, jacobian.shape[1]))
    out[0] = jacobian[0].real
    out[1] = jacobian[0].imag
    return out


@jit
def wheel_rows(frames, params, chain):
    """Each wheel's toe (its rolling direction in its module, the toe angle of `params` turning it) and its velocity
    Jacobian along and across that direction, (W, nv) each, with how many leading coordinates move it."""
    _, _, wheel_module, wheel_offset, wheel_toe = chain
    nw = wheel_module.shape[0]
    toe = np.empty(nw, dtype=np.complex128)
    for w in range(nw):  # loops here and below: each array expression's temporary is an allocation, every step
        angle = params[PER_WHEEL + nw + w]
        toe[w] = wheel_toe[w] * np.exp(1j * angle) if angle != 0.0 else wheel_toe[w]  # exp(0) = 1: 28 exps saved
    _, direction, jacobian = wheel_kinematics_at(frames, wheel_module, wheel_offset, toe)
    nv = jacobian.shape[1]
    jac_long, jac_lat = np.empty((nw, nv)), np.empty((nw, nv))  # rows: v_long + i v_lat of each wheel
    spans = np.empty(nw, dtype=np.int64)
    for w in range(nw):
        along = np.conj(direction[w])
        for a in range(nv):
            local = along * jacobian[w, a]
            jac_long[w, a], jac_lat[w, a] = local.real, local.imag
        spans[w] = jacobian_span(jac_long, jac_lat, w)
    return toe, jac_long, jac_lat, spans


@jit
def servo_terms(v, dt, servo_command, servo_power, servo_gains):
    """The servos' backward-Euler torque clamp(offset - rate v+, +-power) per coordinate (0 for the base's): the PID
    command u_n = Kp (theta - q) + Kd (theta_dot - q_dot) + Ki z at the step's start becomes
    Kp (theta - q - dt v+) + Kd (theta_dot - v+) + Ki z = u_n + Kd q_dot - (Kd + dt Kp) v+."""
    kp, kd = servo_gains
    nv = v.shape[0]
    offset, rate, power = np.zeros(nv), np.zeros(nv), np.zeros(nv)
    for a in range(3, nv):
        offset[a] = servo_command[a - 3] + kd * v[a]
        rate[a] = kd + dt * kp
        power[a] = servo_power[a - 3]
    return offset, rate, power


@jit
def friction_problem(
    x,
    other_force,
    mass_matrix,
    dt,
    params,
    servo_command,
    servo_power,
    servo_gains,
    chain,
    bodies,
    frames=None,
):
    """The implicit step at state x: its StepLaws (wheel Jacobians along and across the wheels, joint damping with a
    failed joint's compliant stop, the friction-law terms, the servos' backward-Euler offset, rate and power, the
    modules' inertias from `bodies` (module_inertias' (nm, 4); none: the solve is dense)), the free momentum (the
    stop's known torque in it), that known torque, and the wheels' toe. `frames`: the chain's frames at x
    (kinematics.chain_frames), when the caller has them."""
    joint_in_parent, joint_in_child, wheel_module, _, _ = chain
    nw = wheel_module.shape[0]
    if frames is None:
        frames = chain_frames(x, joint_in_parent, joint_in_child)
    toe, jac_long, jac_lat, spans = wheel_rows(frames, params, chain)
    nv = x.shape[0] // 2
    v = np.ascontiguousarray(x[nv:])
    joint_damping = np.zeros(nv)
    joint_coulomb = np.zeros(nv)
    state = params[FAILED]
    for j in range(state.shape[0]):
        if state[j] == FREE:
            joint_damping[3 + j], joint_coulomb[3 + j] = params[C_JOINT], params[JOINT_COULOMB]
        elif state[j] == LOCKED:
            joint_damping[3 + j] = LOCKED_DAMPING
    spring, stop_rate = compliant_stop(x, params, dt)
    theta = params[PER_WHEEL + 2 * nw : PER_WHEEL + 2 * nw + NUM_TERMS]
    # The discrepancy model: only the sites with a term (none: the paper's model, an empty view, nothing allocated).
    sites = jac_long[:0]
    if theta.any():
        coefficients = site_coefficients(theta)
        acting = np.zeros(NUM_SITES, dtype=np.bool_)
        for s in range(NUM_SITES):
            acting[s] = coefficients[s].any()
        if acting.any():
            along, across = site_jacobians(x, chain)
            sites = np.empty((int(acting.sum()), 2 * nv + NSK))
            sites[:, :nv], sites[:, nv : 2 * nv] = along[acting], across[acting]
            sites[:, 2 * nv :] = coefficients[acting]
        joint = theta[NUM_TERMS - NJK :]
        for j in range(state.shape[0]):
            if state[j] == FREE:  # bias and spring at the step's start; drag and dry in the implicit solve
                spring[3 + j] += joint[0] - joint[1] * x[3 + j]
                joint_damping[3 + j] += joint[2]
                joint_coulomb[3 + j] += joint[3]
    jac_drag = np.zeros((4, nv))  # the head centre's velocity: the planar joint's x, y rates; then the tail's end
    jac_drag[0, 0] = 1.0
    jac_drag[1, 1] = 1.0
    if params[TETHER_N] > 0.0:
        jac_drag[2:] = tail_end_jacobian(x, chain)
    servo_offset, servo_rate, power = servo_terms(v, dt, servo_command, servo_power, servo_gains)
    joint_rate = np.empty(nv)
    for a in range(nv):
        joint_rate[a] = dt * (joint_damping[a] + stop_rate[a])
    mass_damped = mass_matrix.copy()
    for a in range(nv):
        mass_damped[a, a] += joint_rate[a]
    momentum_free = mass_matrix @ v
    for a in range(nv):
        momentum_free[a] = momentum_free[a] + dt * other_force[a] + dt * spring[a]
    if bodies.shape[0]:
        inertia, motion = chain_inertias(frames, bodies)
    else:
        inertia, motion = np.zeros((0, 3, 3)), np.zeros((0, 3))
    laws = StepLaws(
        jac_long,
        jac_lat,
        spans,
        mass_damped,
        dt,
        params[MU_LONG],
        params[MU_LAT],
        params[C_LONG],
        params[C_LAT],
        params[PER_WHEEL : PER_WHEEL + nw],
        params[EPS],
        params[SHAPE],
        jac_drag,
        np.array([params[HEAD_MU] * params[HEAD_NORMAL], params[TETHER_N]]),
        np.array([params[EPS], TETHER_EPS_M_S]),
        joint_coulomb,
        JOINT_EPS_RAD_S,
        servo_offset,
        servo_rate,
        power,
        sites,
        inertia,
        motion,
        joint_rate,
    )
    return laws, momentum_free, spring, toe


@jit
def site_jacobians(x, chain):
    """(S, nv) each discrepancy site's velocity along and across its module, per unit rate of each coordinate."""
    joint_in_parent, joint_in_child, _, _, _ = chain
    module, offset, unit = site_arrays(chain)
    _, direction, jacobian = wheel_kinematics_kernel(x, joint_in_parent, joint_in_child, module, offset, unit)
    local = np.conj(direction).reshape(-1, 1) * jacobian
    return np.ascontiguousarray(local.real), np.ascontiguousarray(local.imag)


@jit
def friction_step(
    x,
    other_force,
    mass_matrix,
    dt,
    params,
    newton_steps,
    final_step,
    servo_command,
    servo_power,
    servo_gains,
    chain,
    bodies,
    frames=None,
):
    laws, momentum_free, spring, _ = friction_problem(
        x, other_force, mass_matrix, dt, params, servo_command, servo_power, servo_gains, chain, bodies, frames
    )
    force, servo, v_next = _implicit_friction_force(
        laws, mass_matrix, momentum_free, x[x.shape[0] // 2 :], newton_steps, final_step
    )
    for a in range(force.shape[0]):  # the solve's force leaves out the spring it was given as known
        force[a] += spring[a]
    return force, servo, v_next


@jit
def compliant_stop(x, params, dt):
    """A failed (free) joint's compliant stop, the paper's joint-limit PD (section 3): past the onset angle, the
    torque -k (q + dt v+ - onset) - d v+ (backward Euler). Returns its known part -k (|q| - onset) sgn(q) and
    the rate d + dt k that the implicit solve adds to the joint's damping; zeros when k = 0 (the plant's stiff
    limit alone) or the joint is within the onset. The plant's own limit stays behind it, as a hard stop."""
    nv = x.shape[0] // 2
    spring, rate = np.zeros(nv), np.zeros(nv)
    k = params[STOP_K]
    if k <= 0.0:
        return spring, rate
    state = params[FAILED]
    for j in range(state.shape[0]):
        over = abs(x[3 + j]) - params[STOP_ONSET]
        if state[j] == FREE and over > 0.0:
            spring[3 + j] = -np.sign(x[3 + j]) * k * over
            rate[3 + j] = params[STOP_D] + dt * k
    return spring, rate


@dataclasses.dataclass(frozen=True)
class KnownForces:
    """A run's known forces of the implicit step beyond the plant's: kept in the context (a parameter), set per run."""

    extra: tuple = ()  # explicit generalized forces of user effects, f(x) -> (nv,)
    gravity_in_plane: bool = False  # a tilted floor: gravity has a component in the plane of motion


class FrictionForces(LeafSystem):
    """The model's friction as one generalized force on the planar plant, implicit in time:
    the wheels' (Eqs. 4-5), the failed joints' viscous friction c_joint (section 3) and the friction
    terms of the candidate effects (rc1_drake/effects/). The servos' torque is part of the same implicit step.

    Inputs `plant_state` [q; v], `servo_command` (13, the PID's command sampled at the step's start) and
    `servo_power` (13, each servo's torque limit). Outputs `generalized_force` for the plant's
    applied_generalized_force port (friction plus the explicit forces of user effects) and
    `servo_torque` for its actuation port: the servos' torque at the end of the step, the command with
    its proportional and derivative parts taken at the step's end velocity (backward Euler, as SAP
    treats PD actuators), clamped to the servo power. That makes the servos stable at any step, so the
    step is set by accuracy alone. The five coefficients, eps, the effect terms, which joints have
    failed and each wheel's normal force are numeric parameters: a run changes them in its context
    without rebuilding anything. Gravity (a tilted floor) and a user effect's explicit force enter as known
    forces of the step (KnownForces, an abstract parameter): every per-run value lives in the context.
    """

    NEWTON_STEPS = 20  # at most: the solve stops at a step that moves no velocity by NEWTON_FINAL_STEP_M_S

    def __init__(
        self, plant, geometry: ChainGeometry, friction: Friction, sgn_smoothing_m_s: float, *, servo_gains=(0.0, 0.0)
    ):
        """servo_gains: the servo PID's (Kp, Kd), which the implicit step needs."""
        super().__init__()
        self._plant = plant
        self._plant_context = plant.CreateDefaultContext()
        self._payload_applied = (0.0, 0.0)
        self._bodies = module_inertias(plant, self._plant_context)
        self._geometry = geometry.arrays
        self._dt = plant.time_step()
        self._servo_gains = np.array(servo_gains, dtype=float)
        nq = plant.num_positions()
        self._num_wheels = len(geometry.wheel_module)
        normal = geometry.module_mass[geometry.wheel_module] * GRAVITY_M_S2
        scalars = np.zeros(SCALARS)
        scalars[: EPS + 1] = self.pack(friction, sgn_smoothing_m_s)
        scalars[SHAPE] = PAPER_SHAPE
        scalars[HEAD_NORMAL] = geometry.module_mass[0] * GRAVITY_M_S2
        self._param_index = self.DeclareNumericParameter(
            BasicVector(
                np.concatenate([scalars, np.zeros(NUM_JOINTS), normal, np.zeros(self._num_wheels), np.zeros(NUM_TERMS)])
            )
        )
        self._known_index = self.DeclareAbstractParameter(AbstractValue.Make(KnownForces()))
        self._inputs = (
            self.DeclareVectorInputPort("plant_state", 2 * nq),
            self.DeclareVectorInputPort("servo_command", NUM_JOINTS),
            self.DeclareVectorInputPort("servo_power", NUM_JOINTS),
        )
        # Both outputs come from one solve, cached per step.
        step = self.DeclareCacheEntry(
            "implicit_step",
            ValueProducer(allocate=lambda: AbstractValue.Make(np.zeros(nq + NUM_JOINTS)), calc=self._calc_step),
            {self.all_sources_ticket()},
        )
        self.DeclareVectorOutputPort(
            "generalized_force",
            nq,
            lambda context, out: out.SetFromVector(step.Eval(context)[:nq]),
            prerequisites_of_calc={step.ticket()},
        )
        self.DeclareVectorOutputPort(
            "servo_torque",
            NUM_JOINTS,
            lambda context, out: out.SetFromVector(step.Eval(context)[nq:]),
            prerequisites_of_calc={step.ticket()},
        )

    @staticmethod
    def pack(friction: Friction, sgn_smoothing_m_s: float) -> np.ndarray:
        return np.array(
            [friction.c_joint, friction.mu_lat, friction.mu_long, friction.c_lat, friction.c_long, sgn_smoothing_m_s]
        )

    @property
    def num_wheels(self) -> int:
        return self._num_wheels

    def set_known_forces(self, context, forces: KnownForces) -> None:
        """This run's known forces of the step (effects.apply_effects), in its context."""
        context.get_mutable_abstract_parameter(self._known_index).set_value(forces)

    def known_forces(self, context) -> KnownForces:
        return context.get_abstract_parameter(self._known_index).get_value()

    def parameters(self, context) -> np.ndarray:
        """The mutable parameter vector (layout above: C_JOINT .. EPS, effect terms, FAILED, normals, toes)."""
        return context.get_mutable_numeric_parameter(self._param_index).get_mutable_value()

    def _calc_step(self, context, value):
        state_port, command_port, power_port = self._inputs
        x = state_port.Eval(context)
        params = context.get_numeric_parameter(self._param_index).get_value()
        plant, plant_context = self._plant, self._plant_context
        payload = (params[PAYLOAD_KG], params[PAYLOAD_MODULE])
        if payload != self._payload_applied:  # the solve's mass matrix must carry the payload too
            set_payload(plant, plant_context, int(payload[1]), payload[0])
            self._payload_applied = payload
            self._bodies = module_inertias(plant, plant_context)
        plant.SetPositionsAndVelocities(plant_context, x)
        known = self.known_forces(context)
        other = -plant.CalcBiasTerm(plant_context)
        if known.gravity_in_plane:
            other += plant.CalcGravityGeneralizedForces(plant_context)
        # The plant applies gravity and the bias term itself; the extra forces only reach it through this output.
        extra = sum((force(x) for force in known.extra), np.zeros(len(other))) if known.extra else 0.0
        friction, servo, _ = friction_step(
            x,
            other + extra,
            plant.CalcMassMatrix(plant_context),
            self._dt,
            params,
            self.NEWTON_STEPS,
            NEWTON_FINAL_STEP_M_S,
            command_port.Eval(context),
            power_port.Eval(context),
            self._servo_gains,
            self._geometry,
            self._bodies,
        )
        step = value.get_mutable_value()
        step[: len(other)] = friction + extra
        step[len(other) :] = servo[3:]
