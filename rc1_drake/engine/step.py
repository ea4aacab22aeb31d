"""One time step of the RC1 Diagram as a compiled kernel: the same arithmetic, in the same order, as the
Drake step it mirrors (tests/test_engine.py holds the two together).

    1. FrictionForces (friction.py): the implicit wheel, joint and servo solve at the step's start state,
       giving the friction force and the servos' backward-Euler torque;
    2. the discrete plant (SAP): free motion v* = v + dt M^-1 (-C v + g + friction + extra + servo) (Eq. 1;
       the servo clamps its own torque at its power, and the plant adds no clamp: model.add_rc1_plant),
       locked joints held (their velocity 0, the others' the A-norm projection of v*), then the joint
       limits as SAP's unilateral constraints (below), then q+ = q + dt v+.

The joint limits (paper section 3: the restoring torque at +-38 deg) follow Drake's SapDriver and
SapLimitConstraint: a limit is a constraint only if it lies within q0 +- 2 dt max(|v0|, |v*|); its
impulse is gamma = max(0, (v_hat - vc) / R) with vc = +-v_j (lower, upper), v_hat = -g0 / (2 dt),
g0 = the distance to the limit, and R = max(beta^2 / (4 pi^2) w, 1 / (dt k 2 dt)), beta = 0.1, k = 1e12,
w = 1 / A_jj (the Delassus estimate). The step's velocity solves the convex problem
A (v - v*) = sum_i J_i^T gamma_i(J_i v), here exactly, by active-set Newton.
"""

from __future__ import annotations

import collections

import numpy as np

from ..friction import FrictionForces, friction_step, spd_solve
from ..kinematics import chain_frames, jit
from .dynamics import chain_terms

NEWTON_STEPS = FrictionForces.NEWTON_STEPS
LIMIT_BETA = 0.1
LIMIT_STIFFNESS = 1e12
LIMIT_WINDOW = 2.0


@jit
def rigid_regularization(dt):
    """The regularization of a limit as stiff as SAP's: 1 / (dt k (dt + tau_d)), tau_d = dt."""
    return 1.0 / (dt * LIMIT_STIFFNESS * 2.0 * dt)


@jit
def _in_window(q, v, v_star, dt, d, sign, limit):
    """Whether a limit of dof d (sign +1 lower, -1 upper) is within the step's window (module docstring)."""
    dq = LIMIT_WINDOW * dt * max(abs(v[d]), abs(v_star[d]))
    return limit >= q[d] - dq if sign > 0.0 else limit <= q[d] + dq


@jit
def limit_constraints(q, v, v_star, A, dt, lower, upper, locked):
    """SAP's joint-limit constraints of the step (module docstring): for each limit within the window, its
    dof, sign (+1 lower, -1 upper), v_hat and 1/R; returns those arrays and their count. Room for both limits of
    every joint: a window wider than a joint's range (a rate past ~650 rad/s, or a start far beyond a limit) holds
    both."""
    nj = lower.shape[0]
    dofs = np.empty(2 * nj, dtype=np.int64)
    signs = np.empty(2 * nj)
    v_hat = np.empty(2 * nj)
    r_inv = np.empty(2 * nj)
    count = 0
    for j in range(nj):
        d = 3 + j
        if locked[j]:
            continue
        q0 = q[d]
        for sign, limit in ((1.0, lower[j]), (-1.0, upper[j])):
            if _in_window(q, v, v_star, dt, d, sign, limit):
                w = 1.0 / A[d, d]
                R = max(LIMIT_BETA**2 / (4.0 * np.pi**2) * w, rigid_regularization(dt))
                dofs[count] = d
                signs[count] = sign
                v_hat[count] = -sign * (q0 - limit) / (2.0 * dt)
                r_inv[count] = 1.0 / R
                count += 1
    return dofs, signs, v_hat, r_inv, count


@jit
def _near_a_limit(q, v, v_star, dt, lower, upper):
    """Whether any joint is within limit_constraints' window of a limit (no joint locked)."""
    for j in range(lower.shape[0]):
        if _in_window(q, v, v_star, dt, 3 + j, 1.0, lower[j]) or _in_window(q, v, v_star, dt, 3 + j, -1.0, upper[j]):
            return True
    return False


@jit
def _limit_solve(q, v, v_star, A, dt, lower, upper, locked):
    """v+ of the SAP step with joint-limit constraints, locked joints held at rate 0 (module docstring)."""
    nv = v.shape[0]
    out = v_star.copy()
    if not locked.any() and not _near_a_limit(q, v, v_star, dt, lower, upper):
        return out  # most steps: nothing to solve, and nothing to allocate for it
    free = np.ones(nv, dtype=np.bool_)
    free[3:] = ~locked
    if locked.any():  # min |v - v*|_A with v_locked = 0: A_uu v_u = (A v*)_u
        index = np.flatnonzero(free)
        out[:] = 0.0
        out[index] = spd_solve(np.ascontiguousarray(A[index][:, index]), (A @ v_star)[index])
    dofs, signs, v_hat, r_inv, count = limit_constraints(q, v, v_star, A, dt, lower, upper, locked)
    if count == 0:
        return out
    index = np.flatnonzero(free)
    Ar = np.ascontiguousarray(A[index][:, index])
    position = np.full(nv, -1, dtype=np.int64)
    position[index] = np.arange(index.shape[0])
    rhs0 = (A @ v_star)[index]
    vr = out[index].copy()
    active = np.zeros(count, dtype=np.bool_)
    for _ in range(4 * count + 4):  # active-set Newton on a convex piecewise quadratic: a few passes
        changed = False
        for i in range(count):
            now = v_hat[i] - signs[i] * vr[position[dofs[i]]] > 0.0
            if now != active[i]:
                active[i] = now
                changed = True
        if not changed and _ > 0:
            break
        matrix = Ar.copy()
        rhs = rhs0.copy()
        for i in range(count):
            if active[i]:
                r = position[dofs[i]]
                matrix[r, r] += r_inv[i]
                rhs[r] += signs[i] * v_hat[i] * r_inv[i]
        vr = spd_solve(matrix, rhs)
    out[index] = vr
    return out


# The chain's numbers a step takes (a run builds them once; the failure switch edits `locked` in place): module
# masses, yaw inertias and centres of mass, gravity's floor component and whether it acts in the plane, the joint
# limits, the locked joints, and the chain's geometry (kinematics.ChainGeometry.arrays).
PlantTerms = collections.namedtuple(
    "PlantTerms",
    ["mass", "yaw_inertia", "com", "gravity_xy", "gravity_in_plane", "lower", "upper", "locked", "chain", "bodies"],
)


@jit
def plant_terms(mass, yaw_inertia, com, gravity_xy, gravity_in_plane, lower, upper, locked, chain):
    """PlantTerms, with the modules as the O(n) solve takes them (model.module_inertias' layout)."""
    bodies = np.empty((mass.shape[0], 4))
    bodies[:, 0], bodies[:, 1], bodies[:, 2], bodies[:, 3] = mass, yaw_inertia, com.real, com.imag
    return PlantTerms(mass, yaw_inertia, com, gravity_xy, gravity_in_plane, lower, upper, locked, chain, bodies)


@jit
def plant_step(
    x,
    dt,
    params,
    servo_command,
    servo_power,
    servo_gains,
    extra_force,
    plant,
    final_step,
):
    """(x+, servo torque (13,), v*, the force that gives the friction solve's v+ = v + dt M^-1 force) of one
    Diagram step from state x (module docstring)."""
    mass, yaw_inertia, com, gravity_xy, gravity_in_plane, lower, upper, locked, chain, bodies = plant
    joint_in_parent, joint_in_child, _, _, _ = chain
    nv = x.shape[0] // 2
    frames = chain_frames(x, joint_in_parent, joint_in_child)  # once: the chain's terms and the friction take them
    M, bias, gravity = chain_terms(x, mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy, frames)
    known = np.empty(nv)  # -bias (+ gravity in the plane) + extra_force, in loops: no temporaries, every step
    for a in range(nv):
        known[a] = (-bias[a] + gravity[a] if gravity_in_plane else -bias[a]) + extra_force[a]
    friction, servo, v_solved = friction_step(
        x,
        known,
        M,
        dt,
        params,
        NEWTON_STEPS,
        final_step,
        servo_command,
        servo_power,
        servo_gains,
        chain,
        bodies,
        frames,
    )
    v = x[nv:]
    if gravity_in_plane or not gravity.any():
        v_star = v_solved  # M (v* - v) = dt (the step's forces) is the equation the friction solve's v+ satisfies
    else:  # gravity that the friction solve was not told of (the plant applies its gravity field itself)
        tau = -bias + gravity + friction + extra_force
        tau[3:] += servo[3:]
        v_star = v + dt * spd_solve(M, tau)
    v_next = _limit_solve(x[:nv], v, v_star, M, dt, lower, upper, locked)
    out = np.empty_like(x)
    for a in range(nv):
        out[a], out[nv + a] = x[a] + dt * v_next[a], v_next[a]
        known[a] = known[a] + friction[a] + servo[a]  # the force the step applied: with v*, for tangent.py
    return out, servo[3:].copy(), v_star, known
