"""The step's tangent-linear model: forward sensitivities of a run with respect to the friction coefficients
and the friction-law effects (CompiledSession.simulate(..., sensitivities=...)).

x_{k+1} = step(x_k, p) is differentiated stage by stage (step.py): the chain's terms and the wheels' local
Jacobians along the state's sensitivity, the implicit friction and servo solve by the implicit function
theorem (its Newton matrix, exact), locked joints and the limits' active set.

Differentiating the chain recursion of kinematics.py: with delta_phi_k = delta_yaw + sum_{j<k} delta_q_j,
e_k = exp(i phi_k) moves by i delta_phi_k e_k, so a point r fixed in module k moves by i delta_phi_k R(phi_k) r,
and the Jacobian column i (c - c_j) of a point c about a joint c_j moves by i (delta_c - delta_c_j). Each
term below is the exact derivative of its counterpart in dynamics.chain_terms / friction.friction_step;
tests/test_tangent.py checks them against central differences.
"""

from __future__ import annotations

import numpy as np

from ..discrepancy import NJK, NSK, NUM_TERMS, SITE_GROUP, joint_shapes, site_arrays, site_force, site_shapes
from ..friction import (
    C_JOINT,
    C_LAT,
    C_LONG,
    FAILED,
    FREE,
    HEAD_MU,
    HEAD_NORMAL,
    JOINT_COULOMB,
    JOINT_EPS_RAD_S,
    MU_LAT,
    MU_LONG,
    PER_WHEEL,
    SHAPE,
    assemble_step,
    cholesky,
    cholesky_solve,
    coulomb_law,
    friction_problem,
    lu_solve,
    spd_solve,
)
from ..kinematics import jit
from .dynamics import chain_terms
from .step import LIMIT_BETA, limit_constraints, rigid_regularization


@jit
def chain_tangent(x, dx, w, mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy):
    """For each direction dx[p] (P, 32): (dM dx[p]) w[p], d(C v) and dg, each (P, 16), where M, C v and g
    are dynamics.chain_terms' at x and w (P, 16) is the vector the mass matrix's derivative multiplies."""
    nj = joint_in_parent.shape[0]
    nm = nj + 1
    nv = nj + 3
    num = dx.shape[0]
    phi = np.cumsum(x[2:nv])
    phi_dot = np.cumsum(x[nv + 2 :])
    e = np.exp(1j * phi)
    out_mw = np.zeros((num, nv))
    out_bias = np.zeros((num, nv))
    out_gravity = np.zeros((num, nv))
    p = np.empty(nm, dtype=np.complex128)
    acc = np.empty(nm, dtype=np.complex128)
    joint_xy = np.empty(nj, dtype=np.complex128)
    dp = np.empty(nm, dtype=np.complex128)
    dacc = np.empty(nm, dtype=np.complex128)
    djoint = np.empty(nj, dtype=np.complex128)
    jac = np.empty(nv, dtype=np.complex128)
    djac = np.empty(nv, dtype=np.complex128)
    for d in range(num):
        dphi = np.cumsum(dx[d, 2:nv])
        dphi_dot = np.cumsum(dx[d, nv + 2 :])
        p[0] = x[0] + 1j * x[1]
        dp[0] = dx[d, 0] + 1j * dx[d, 1]
        acc[0] = 0.0
        dacc[0] = 0.0
        for j in range(nj):
            a = e[j] * joint_in_parent[j]
            b = e[j + 1] * joint_in_child[j]
            da = 1j * dphi[j] * a
            db = 1j * dphi[j + 1] * b
            joint_xy[j] = p[j] + a
            djoint[j] = dp[j] + da
            p[j + 1] = p[j] + a - b
            dp[j + 1] = dp[j] + da - db
            acc[j + 1] = acc[j] - phi_dot[j] ** 2 * a + phi_dot[j + 1] ** 2 * b
            dacc[j + 1] = (
                dacc[j]
                - 2.0 * phi_dot[j] * dphi_dot[j] * a
                - phi_dot[j] ** 2 * da
                + 2.0 * phi_dot[j + 1] * dphi_dot[j + 1] * b
                + phi_dot[j + 1] ** 2 * db
            )
        for k in range(nm):
            r = e[k] * com[k]
            dr = 1j * dphi[k] * r
            c = p[k] + r
            dc = dp[k] + dr
            a_k = acc[k] - phi_dot[k] ** 2 * r
            da_k = dacc[k] - 2.0 * phi_dot[k] * dphi_dot[k] * r - phi_dot[k] ** 2 * dr
            n = 3 + k
            jac[0], djac[0] = 1.0, 0.0
            jac[1], djac[1] = 1j, 0.0
            jac[2], djac[2] = 1j * (c - p[0]), 1j * (dc - dp[0])
            for j in range(k):
                jac[3 + j] = 1j * (c - joint_xy[j])
                djac[3 + j] = 1j * (dc - djoint[j])
            jw, djw = 0.0 + 0.0j, 0.0 + 0.0j
            for i in range(n):
                jw += jac[i] * w[d, i]
                djw += djac[i] * w[d, i]
            m = mass[k]
            for i in range(n):
                out_mw[d, i] += m * (np.conj(djac[i]) * jw + np.conj(jac[i]) * djw).real
                out_bias[d, i] += m * (np.conj(djac[i]) * a_k + np.conj(jac[i]) * da_k).real
                out_gravity[d, i] += m * (np.conj(djac[i]) * gravity_xy).real
    return out_mw, out_bias, out_gravity


@jit
def wheel_local_tangent(x, dx, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe):
    """The wheels' local Jacobians L_w = conj(direction_w) J_w (rows: v_long + i v_lat, friction.friction_step)
    at x, (W, 16) complex, and their derivatives along each direction dx[p], (P, W, 16) complex."""
    nj = joint_in_parent.shape[0]
    nv = nj + 3
    nw = wheel_module.shape[0]
    num = dx.shape[0]
    phi = np.cumsum(x[2:nv])
    e = np.exp(1j * phi)
    p = np.empty(nj + 1, dtype=np.complex128)
    joint_xy = np.empty(nj, dtype=np.complex128)
    p[0] = x[0] + 1j * x[1]
    for j in range(nj):
        joint_xy[j] = p[j] + e[j] * joint_in_parent[j]
        p[j + 1] = joint_xy[j] - e[j + 1] * joint_in_child[j]
    local = np.zeros((nw, nv), dtype=np.complex128)
    for w in range(nw):
        k = wheel_module[w]
        position = p[k] + e[k] * wheel_offset[w]
        turn = np.conj(e[k] * wheel_toe[w])
        local[w, 0] = turn
        local[w, 1] = turn * 1j
        local[w, 2] = turn * 1j * (position - p[0])
        for j in range(k):
            local[w, 3 + j] = turn * 1j * (position - joint_xy[j])
    dlocal = np.zeros((num, nw, nv), dtype=np.complex128)
    dp = np.empty(nj + 1, dtype=np.complex128)
    djoint = np.empty(nj, dtype=np.complex128)
    for d in range(num):
        dphi = np.cumsum(dx[d, 2:nv])
        dp[0] = dx[d, 0] + 1j * dx[d, 1]
        for j in range(nj):
            djoint[j] = dp[j] + 1j * dphi[j] * e[j] * joint_in_parent[j]
            dp[j + 1] = djoint[j] - 1j * dphi[j + 1] * e[j + 1] * joint_in_child[j]
        for w in range(nw):
            k = wheel_module[w]
            position = p[k] + e[k] * wheel_offset[w]
            dposition = dp[k] + 1j * dphi[k] * e[k] * wheel_offset[w]
            turn = np.conj(e[k] * wheel_toe[w])
            dturn = -1j * dphi[k] * turn  # conj(i dphi e) = -i dphi conj(e)
            dlocal[d, w, 0] = dturn
            dlocal[d, w, 1] = dturn * 1j
            dlocal[d, w, 2] = 1j * (dturn * (position - p[0]) + turn * (dposition - dp[0]))
            for j in range(k):
                dlocal[d, w, 3 + j] = 1j * (dturn * (position - joint_xy[j]) + turn * (dposition - djoint[j]))
    return local, dlocal


@jit
def _coulomb_partials(u, mu_n, eps, asymmetry, ratio, speed):
    """d/d(mu N), d/da and d/dr of friction.coulomb_law's Coulomb term mu N (1 + a s)(1 + r d) s."""
    s = u / np.sqrt(u * u + eps * eps)
    decay = np.exp(-((u / speed) ** 2))  # also at r = 0, where d/dr needs it
    return (
        (1.0 + asymmetry * s) * (1.0 + ratio * decay) * s,
        mu_n * s * s * (1.0 + ratio * decay),
        mu_n * (1.0 + asymmetry * s) * decay * s,
    )


@jit
def friction_tangent(
    x,
    dx,
    dparams,
    dcommand,
    dother,
    dmass_w,
    v_plus,
    mass_matrix,
    other_force,
    dt,
    params,
    servo_command,
    servo_power,
    servo_gains,
    chain,
):
    """The friction solve's velocity v+ (friction.friction_step) differentiated along P directions: the state
    dx (P, 32), the parameter vector dparams (P, len(params)), the servo command dcommand (P, 13) and the other
    generalized forces dother (P, 16); dmass_w (P, 16) is (dM dx) (v+ - v). By the implicit function theorem on
    the step's residual R(v+) = M~ v+ - M v - dt other - dt F(v+) = 0: dv+ = -K^-1 dR, with K the Newton
    matrix at v+ (friction.assemble_step's exact tangent: the solve's own clips a falling Stribeck law) and dR the
    residual's change at fixed v+."""
    joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe = chain
    nv = x.shape[0] // 2
    nw = wheel_module.shape[0]
    laws, _, _, toe = friction_problem(
        x, other_force, mass_matrix, dt, params, servo_command, servo_power, servo_gains, chain
    )
    _, K, linear = assemble_step(v_plus, True, laws, True)
    jac_long, jac_lat, spans, normal, eps, shape = (laws.jac_long, laws.jac_lat, laws.spans, laws.normal_force,
                                                    laws.eps, laws.shape)  # fmt: skip
    mu_long, mu_lat, c_long, c_lat = laws.mu_long, laws.mu_lat, laws.c_long, laws.c_lat
    # The exact tangent may lose definiteness where a Stribeck law falls, or symmetry with a discrepancy term: LU then
    low = cholesky(K) if laws.sites.shape[0] == 0 else np.zeros((0, 0))
    local, dlocal = wheel_local_tangent(x, dx, joint_in_parent, joint_in_child, wheel_module, wheel_offset, toe)
    free = params[FAILED] == FREE
    kd = servo_gains[1]
    disc = slice(PER_WHEEL + 2 * nw, PER_WHEEL + 2 * nw + NUM_TERMS)
    theta = params[disc]
    sites = theta.any() or dparams[:, disc].any()
    if sites:
        module, offset, unit = site_arrays(chain)
        site_local, site_dlocal = wheel_local_tangent(x, dx, joint_in_parent, joint_in_child, module, offset, unit)
    out = np.empty((dx.shape[0], nv))
    for d in range(dx.shape[0]):
        dp = dparams[d]
        dR = dmass_w[d] - mass_matrix @ dx[d, nv:] - dt * dother[d]
        dR[3:] += dt * dp[C_JOINT] * np.where(free, v_plus[3:], 0.0)
        dF = np.zeros(nv)
        for w in range(nw):
            u = 0.0 + 0.0j
            du = 0.0 + 0.0j
            for a in range(spans[w]):
                u += local[w, a] * v_plus[a]
                du += dlocal[d, w, a] * v_plus[a]
            dtoe = dp[PER_WHEEL + nw + w]
            du += -1j * u * dtoe  # a toe turns the wheel's frame: dL/dtoe = -i L
            n_w, dn_w = normal[w], dp[PER_WHEEL + w]
            c_l, _, t_l = coulomb_law(u.real, mu_long * n_w, eps, shape[1], 0.0, shape[3], False)
            c_t, _, t_t = coulomb_law(u.imag, mu_lat * n_w, eps, shape[0], shape[2], shape[3], False)
            f_l, f_t = -(c_long * u.real + c_l), -(c_lat * u.imag + c_t)
            pl_mu, pl_a, _ = _coulomb_partials(u.real, mu_long * n_w, eps, shape[1], 0.0, shape[3])
            pt_mu, pt_a, pt_r = _coulomb_partials(u.imag, mu_lat * n_w, eps, shape[0], shape[2], shape[3])
            df_l = (
                -(c_long + t_l) * du.real
                - dp[C_LONG] * u.real
                - pl_mu * (dp[MU_LONG] * n_w + mu_long * dn_w)
                - pl_a * dp[SHAPE][1]
            )
            df_t = (
                -(c_lat + t_t) * du.imag
                - dp[C_LAT] * u.imag
                - pt_mu * (dp[MU_LAT] * n_w + mu_lat * dn_w)
                - pt_a * dp[SHAPE][0]
                - pt_r * dp[SHAPE][2]
            )
            for a in range(spans[w]):
                dlocal_a = dlocal[d, w, a] - 1j * local[w, a] * dtoe
                dF[a] += dlocal_a.real * f_l + dlocal_a.imag * f_t + jac_long[w, a] * df_l + jac_lat[w, a] * df_t
        for j in range(3, nv):
            if free[j - 3]:
                dF[j] -= dp[JOINT_COULOMB] * v_plus[j] / np.sqrt(v_plus[j] ** 2 + JOINT_EPS_RAD_S**2)
            dF[j] += linear[j] * (dcommand[d, j - 3] + kd * dx[d, nv + j])
        if sites:
            dF += _discrepancy_tangent(site_local, site_dlocal[d], v_plus, x, dx[d], theta, dp[disc], free, eps)
        head = dp[HEAD_MU] * params[HEAD_NORMAL] + params[HEAD_MU] * dp[HEAD_NORMAL]
        if head != 0.0:
            root = np.sqrt(v_plus[0] ** 2 + v_plus[1] ** 2 + eps * eps)
            dF[0] -= head * v_plus[0] / root
            dF[1] -= head * v_plus[1] / root
        dR -= dt * dF
        out[d] = -(cholesky_solve(low, dR) if low.shape[0] else lu_solve(K, dR))
    return out


@jit
def _discrepancy_tangent(local, dlocal, v_plus, x, dx, theta, dtheta, free, eps):
    """The discrepancy force's change (discrepancy.py) at fixed v+ along one direction: the sites' Jacobians move
    with the state (dlocal), the coefficients by dtheta; in failed joints the bias and spring (at the step's
    start) move with the angle too. Its change with v+ is in the Newton matrix (friction.assemble_step)."""
    nv = v_plus.shape[0]
    out = np.zeros(nv)
    for s in range(local.shape[0]):
        g = SITE_GROUP[s]
        if g < 0:
            continue
        u, du = 0.0 + 0.0j, 0.0 + 0.0j
        for a in range(nv):
            u += local[s, a] * v_plus[a]
            du += dlocal[s, a] * v_plus[a]
        coeff, dcoeff = theta[g * NSK : (g + 1) * NSK], dtheta[g * NSK : (g + 1) * NSK]
        f, rate = site_force(u.real, u.imag, coeff, eps)
        df = rate[:, 0] * du.real + rate[:, 1] * du.imag + site_shapes(u.real, u.imag, eps) @ dcoeff
        for a in range(nv):
            out[a] += dlocal[s, a].real * f[0] + dlocal[s, a].imag * f[1] + local[s, a].real * df[0]
            out[a] += local[s, a].imag * df[1]
    joint, djoint = theta[NUM_TERMS - NJK :], dtheta[NUM_TERMS - NJK :]
    for j in range(free.shape[0]):
        if free[j]:
            k = 3 + j
            known = joint_shapes(x[k], v_plus[k], JOINT_EPS_RAD_S)  # bias, spring at the start; drag, dry at v+
            out[k] += djoint @ known - joint[1] * dx[k]
    return out


@jit
def _rows(w, num):
    """w (n,) repeated as num rows."""
    out = np.empty((num, w.shape[0]))
    out[:] = w
    return out


@jit
def step_tangent(
    x,
    force_plus,
    v_star,
    v_new,
    S,
    dparams,
    dgravity,
    dcommand,
    dt,
    params,
    servo_command,
    servo_power,
    servo_gains,
    plant,
):
    """d x_{k+1} (P, 32) of step.py's plant_step along state directions S (P, 32), parameter directions dparams,
    gravity's floor components dgravity (P, 2) and command directions dcommand, given the step's forces and
    velocities: the friction solve's v+ = v + dt M^-1 force_plus, v* (the free motion) and v_new (after locked
    joints and limits). Each stage is differentiated as it is computed (step.py)."""
    mass, yaw_inertia, com, gravity_xy, in_plane, lower, upper, locked, chain = plant
    joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe = chain
    nv = x.shape[0] // 2
    num = S.shape[0]
    v = x[nv:]
    M, bias, gravity = chain_terms(x, mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy)
    v_plus = v + dt * spd_solve(M, force_plus)
    other = -bias + (gravity if in_plane else np.zeros(nv))
    mw, dbias, dgravity_x = chain_tangent(
        x, S, _rows(v_plus - v, num), mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy
    )
    dother = -dbias + (dgravity_x if in_plane else np.zeros_like(dbias))
    for d in range(num):
        if dgravity[d, 0] != 0.0 or dgravity[d, 1] != 0.0:  # the generalized gravity force is linear in the field
            dother[d] += chain_terms(
                x, mass, yaw_inertia, com, joint_in_parent, joint_in_child, dgravity[d, 0] + 1j * dgravity[d, 1]
            )[2]
    dv = friction_tangent(
        x,
        S,
        dparams,
        dcommand,
        dother,
        mw,
        v_plus,
        M,
        other,
        dt,
        params,
        servo_command,
        servo_power,
        servo_gains,
        chain,
    )
    # Locked joints and the limits' active set (step._limit_solve): (A_r + D) v_r = (A v*)_r + h, with D = 1/R
    # and h = sign v_hat / R on the active constraints.
    dofs, signs, v_hat, r_inv, count = limit_constraints(x[:nv], v, v_star, M, dt, lower, upper, locked)
    active = np.zeros(count, dtype=np.bool_)
    for i in range(count):
        active[i] = v_hat[i] - signs[i] * v_new[dofs[i]] > 0.0
    if locked.any() or active.any():
        free = np.ones(nv, dtype=np.bool_)
        free[3:] = ~locked
        index = np.flatnonzero(free)
        position = np.full(nv, -1, dtype=np.int64)
        position[index] = np.arange(index.shape[0])
        matrix = M[index][:, index].copy()
        mwn = chain_tangent(
            x, S, _rows(v_star - v_new, num), mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy
        )[0]
        rhs = np.empty((num, index.shape[0]))
        for d in range(num):
            rhs[d] = (mwn[d] + M @ dv[d])[index]
        c = LIMIT_BETA**2 / (4.0 * np.pi**2)
        for i in range(count):
            if not active[i]:
                continue
            k, r, R = dofs[i], position[dofs[i]], 1.0 / r_inv[i]
            unit = np.zeros((num, nv))
            unit[:, k] = 1.0
            dA_kk = chain_tangent(x, S, unit, mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy)[0][
                :, k
            ]
            matrix[r, r] += r_inv[i]
            for d in range(num):
                dR = -c * dA_kk[d] / M[k, k] ** 2 if c / M[k, k] > rigid_regularization(dt) else 0.0
                dv_hat = -signs[i] * S[d, k] / (2.0 * dt)
                rhs[d, r] += signs[i] * (dv_hat / R - v_hat[i] * dR / R**2) + dR / R**2 * v_new[k]
        for d in range(num):
            solved = spd_solve(matrix, rhs[d])
            dv[d, :] = 0.0
            dv[d, index] = solved
    out = np.empty((num, 2 * nv))
    out[:, :nv] = S[:, :nv] + dt * dv
    out[:, nv:] = dv
    return out
