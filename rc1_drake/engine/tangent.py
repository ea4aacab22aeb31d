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
    STOP_D,
    STOP_K,
    STOP_ONSET,
    assemble_step,
    cholesky,
    cholesky_solve,
    compliant_stop,
    coulomb_law,
    friction_problem,
    lu_factor,
    lu_factor_solve,
    spd_solve,
)
from ..kinematics import chain_frames, jit
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
    # The chain at x, once for every direction: the joints' arms (a, b), positions and accelerations, and each
    # module's centre of mass, its arm r, its acceleration and its Jacobian row.
    a = e[:nj] * joint_in_parent
    b = e[1:] * joint_in_child
    p = np.empty(nm, dtype=np.complex128)
    acc = np.empty(nm, dtype=np.complex128)
    joint_xy = np.empty(nj, dtype=np.complex128)
    p[0] = x[0] + 1j * x[1]
    acc[0] = 0.0
    for j in range(nj):
        joint_xy[j] = p[j] + a[j]
        p[j + 1] = p[j] + a[j] - b[j]
        acc[j + 1] = acc[j] - phi_dot[j] ** 2 * a[j] + phi_dot[j + 1] ** 2 * b[j]
    r = e * com
    c = p + r
    a_com = np.empty(nm, dtype=np.complex128)
    jac = np.zeros((nm, nv), dtype=np.complex128)
    for k in range(nm):
        a_com[k] = acc[k] - phi_dot[k] ** 2 * r[k]
        jac[k, 0], jac[k, 1], jac[k, 2] = 1.0, 1j, 1j * (c[k] - p[0])
        for j in range(k):
            jac[k, 3 + j] = 1j * (c[k] - joint_xy[j])
    dp = np.empty(nm, dtype=np.complex128)
    dacc = np.empty(nm, dtype=np.complex128)
    djoint = np.empty(nj, dtype=np.complex128)
    djac = np.empty(nv, dtype=np.complex128)
    for d in range(num):
        dphi = np.cumsum(dx[d, 2:nv])
        dphi_dot = np.cumsum(dx[d, nv + 2 :])
        dp[0] = dx[d, 0] + 1j * dx[d, 1]
        dacc[0] = 0.0
        for j in range(nj):
            da = 1j * dphi[j] * a[j]
            db = 1j * dphi[j + 1] * b[j]
            djoint[j] = dp[j] + da
            dp[j + 1] = dp[j] + da - db
            dacc[j + 1] = (
                dacc[j]
                - 2.0 * phi_dot[j] * dphi_dot[j] * a[j]
                - phi_dot[j] ** 2 * da
                + 2.0 * phi_dot[j + 1] * dphi_dot[j + 1] * b[j]
                + phi_dot[j + 1] ** 2 * db
            )
        for k in range(nm):
            dr = 1j * dphi[k] * r[k]
            dc = dp[k] + dr
            da_k = dacc[k] - 2.0 * phi_dot[k] * dphi_dot[k] * r[k] - phi_dot[k] ** 2 * dr
            n = 3 + k
            djac[0], djac[1], djac[2] = 0.0, 0.0, 1j * (dc - dp[0])
            for j in range(k):
                djac[3 + j] = 1j * (dc - djoint[j])
            jw, djw = 0.0 + 0.0j, 0.0 + 0.0j
            for i in range(n):
                jw += jac[k, i] * w[d, i]
                djw += djac[i] * w[d, i]
            m = mass[k]
            for i in range(n):
                out_mw[d, i] += m * (np.conj(djac[i]) * jw + np.conj(jac[k, i]) * djw).real
                out_bias[d, i] += m * (np.conj(djac[i]) * a_com[k] + np.conj(jac[k, i]) * da_k).real
                out_gravity[d, i] += m * (np.conj(djac[i]) * gravity_xy).real
    return out_mw, out_bias, out_gravity


@jit
def wheel_frame(x, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe):
    """The wheels' local Jacobians L_w = conj(direction_w) J_w (rows: v_long + i v_lat, friction.friction_step)
    at x, (W, 16) complex, and the chain's terms wheel_local_direction takes: (local, e, p, joint_xy)."""
    nv = joint_in_parent.shape[0] + 3
    nw = wheel_module.shape[0]
    e, p, joint_xy = chain_frames(x, joint_in_parent, joint_in_child)
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
    return local, e, p, joint_xy


@jit
def wheel_local_direction(dx, frame, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe, out):
    """The local Jacobians' derivative along one state direction dx (32,) into `out` (W, 16) complex (columns past
    a wheel's span are left as they are: zero in a fresh buffer); `frame`: wheel_frame's at the state."""
    _, e, p, joint_xy = frame
    nj = joint_in_parent.shape[0]
    nv = nj + 3
    dphi = np.cumsum(dx[2:nv])
    dp = np.empty(nj + 1, dtype=np.complex128)
    djoint = np.empty(nj, dtype=np.complex128)
    dp[0] = dx[0] + 1j * dx[1]
    for j in range(nj):
        djoint[j] = dp[j] + 1j * dphi[j] * e[j] * joint_in_parent[j]
        dp[j + 1] = djoint[j] - 1j * dphi[j + 1] * e[j + 1] * joint_in_child[j]
    for w in range(wheel_module.shape[0]):
        k = wheel_module[w]
        position = p[k] + e[k] * wheel_offset[w]
        dposition = dp[k] + 1j * dphi[k] * e[k] * wheel_offset[w]
        turn = np.conj(e[k] * wheel_toe[w])
        dturn = -1j * dphi[k] * turn  # conj(i dphi e) = -i dphi conj(e)
        out[w, 0] = dturn
        out[w, 1] = dturn * 1j
        out[w, 2] = 1j * (dturn * (position - p[0]) + turn * (dposition - dp[0]))
        for j in range(k):
            out[w, 3 + j] = 1j * (dturn * (position - joint_xy[j]) + turn * (dposition - djoint[j]))


@jit
def wheel_local_tangent(x, dx, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe):
    """The wheels' local Jacobians at x, (W, 16) complex (wheel_frame), and their derivatives along each direction
    dx[p], (P, W, 16) complex."""
    frame = wheel_frame(x, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe)
    dlocal = np.zeros((dx.shape[0], wheel_module.shape[0], x.shape[0] // 2), dtype=np.complex128)
    for d in range(dx.shape[0]):
        wheel_local_direction(dx[d], frame, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe,
                              dlocal[d])  # fmt: skip
    return frame[0], dlocal


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
def _wheel_laws(local, v_plus, laws):
    """What friction_tangent takes of each wheel that does not depend on the direction, once per step: its slip
    (v_long + i v_lat) and its law's terms (rows: the slope along and across, the forces f_long and f_lat, then
    _coulomb_partials' along (mu, a) and across (mu, a, r))."""
    spans, normal, eps, shape = laws.spans, laws.normal_force, laws.eps, laws.shape
    mu_long, mu_lat, c_long, c_lat = laws.mu_long, laws.mu_lat, laws.c_long, laws.c_lat
    nw = local.shape[0]
    slip = np.empty(nw, dtype=np.complex128)
    law = np.empty((nw, 9))
    for w in range(nw):
        u = 0.0 + 0.0j
        for a in range(spans[w]):
            u += local[w, a] * v_plus[a]
        slip[w] = u
        n_w = normal[w]
        c_l, _, t_l = coulomb_law(u.real, mu_long * n_w, eps, shape[1], 0.0, shape[3], False)
        c_t, _, t_t = coulomb_law(u.imag, mu_lat * n_w, eps, shape[0], shape[2], shape[3], False)
        law[w, 0], law[w, 1] = c_long + t_l, c_lat + t_t
        law[w, 2], law[w, 3] = -(c_long * u.real + c_l), -(c_lat * u.imag + c_t)
        law[w, 4], law[w, 5], _ = _coulomb_partials(u.real, mu_long * n_w, eps, shape[1], 0.0, shape[3])
        law[w, 6], law[w, 7], law[w, 8] = _coulomb_partials(u.imag, mu_lat * n_w, eps, shape[0], shape[2], shape[3])
    return slip, law


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
        x, other_force, mass_matrix, dt, params, servo_command, servo_power, servo_gains, chain, np.zeros((0, 4))
    )
    _, K, linear = assemble_step(v_plus, True, laws, True)
    jac_long, jac_lat, spans, normal, eps = laws.jac_long, laws.jac_lat, laws.spans, laws.normal_force, laws.eps
    mu_long, mu_lat = laws.mu_long, laws.mu_lat
    # The exact tangent may lose definiteness where a Stribeck law falls, or symmetry with a discrepancy term: LU then
    low = cholesky(K) if laws.sites.shape[0] == 0 else np.zeros((0, 0))
    frame = wheel_frame(x, joint_in_parent, joint_in_child, wheel_module, wheel_offset, toe)
    local, dlocal = frame[0], np.zeros((nw, nv), dtype=np.complex128)  # dlocal: one direction's, refilled
    free = params[FAILED] == FREE
    kd = servo_gains[1]
    disc = slice(PER_WHEEL + 2 * nw, PER_WHEEL + 2 * nw + NUM_TERMS)
    theta = params[disc]
    sites = theta.any() or dparams[:, disc].any()
    if sites:
        module, offset, unit = site_arrays(chain)
        site_frame = wheel_frame(x, joint_in_parent, joint_in_child, module, offset, unit)
        site_local, site_dlocal = site_frame[0], np.zeros((module.shape[0], nv), dtype=np.complex128)
    slip, law = _wheel_laws(local, v_plus, laws)
    if sites:
        site_terms = _discrepancy_terms(site_local, v_plus, x, theta, free, eps)
    out = np.empty((dx.shape[0], nv))
    moving = np.ascontiguousarray(dx[:, nv:]) @ np.ascontiguousarray(mass_matrix.T)  # M dv, every direction at once
    free_rate = np.where(free, v_plus[3:], 0.0)
    k_stop = params[STOP_K]  # sgn(q) of the free joints in a compliant stop: where the stop adds its rate
    in_stop = np.where(compliant_stop(x, params, dt)[1] != 0.0, np.sign(x[:nv]), 0.0)
    for d in range(dx.shape[0]):
        dp = dparams[d]
        dR = dmass_w[d] - moving[d] - dt * dother[d]
        dR[3:] += dt * dp[C_JOINT] * free_rate
        dF = np.zeros(nv)
        wheel_local_direction(dx[d], frame, joint_in_parent, joint_in_child, wheel_module, wheel_offset, toe, dlocal)
        for w in range(nw):
            u = slip[w]
            du = 0.0 + 0.0j
            for a in range(spans[w]):
                du += dlocal[w, a] * v_plus[a]
            dtoe = dp[PER_WHEEL + nw + w]
            du += -1j * u * dtoe  # a toe turns the wheel's frame: dL/dtoe = -i L
            n_w, dn_w = normal[w], dp[PER_WHEEL + w]
            df_l = (
                -law[w, 0] * du.real
                - dp[C_LONG] * u.real
                - law[w, 4] * (dp[MU_LONG] * n_w + mu_long * dn_w)
                - law[w, 5] * dp[SHAPE][1]
            )
            df_t = (
                -law[w, 1] * du.imag
                - dp[C_LAT] * u.imag
                - law[w, 6] * (dp[MU_LAT] * n_w + mu_lat * dn_w)
                - law[w, 7] * dp[SHAPE][0]
                - law[w, 8] * dp[SHAPE][2]
            )
            f_l, f_t = law[w, 2], law[w, 3]
            for a in range(spans[w]):
                dlocal_a = dlocal[w, a] - 1j * local[w, a] * dtoe
                dF[a] += dlocal_a.real * f_l + dlocal_a.imag * f_t + jac_long[w, a] * df_l + jac_lat[w, a] * df_t
        for j in range(3, nv):
            if free[j - 3]:
                dF[j] -= dp[JOINT_COULOMB] * v_plus[j] / np.sqrt(v_plus[j] ** 2 + JOINT_EPS_RAD_S**2)
            dF[j] += linear[j] * (dcommand[d, j - 3] + kd * dx[d, nv + j])
            if in_stop[j] != 0.0:  # -k (q - onset sgn q) - (d + dt k) v+ (friction.compliant_stop), at fixed v+
                over = abs(x[j]) - params[STOP_ONSET]
                dk = dp[STOP_K]
                dF[j] -= k_stop * (dx[d, j] - in_stop[j] * dp[STOP_ONSET]) + in_stop[j] * over * dk
                dF[j] -= (dp[STOP_D] + dt * dk) * v_plus[j]
        if sites:
            wheel_local_direction(dx[d], site_frame, joint_in_parent, joint_in_child, module, offset, unit, site_dlocal)
            dF += _discrepancy_tangent(site_local, site_dlocal, v_plus, dx[d], theta, dp[disc], free, site_terms)
        head = dp[HEAD_MU] * params[HEAD_NORMAL] + params[HEAD_MU] * dp[HEAD_NORMAL]
        if head != 0.0:
            root = np.sqrt(v_plus[0] ** 2 + v_plus[1] ** 2 + eps * eps)
            dF[0] -= head * v_plus[0] / root
            dF[1] -= head * v_plus[1] / root
        dR -= dt * dF
        out[d] = -dR
    if low.shape[0]:
        for d in range(out.shape[0]):
            out[d] = cholesky_solve(low, out[d])
        return out
    factors, order = lu_factor(K)  # once a step, for every direction
    for d in range(out.shape[0]):
        out[d] = lu_factor_solve(factors, order, out[d])
    return out


@jit
def _discrepancy_terms(local, v_plus, x, theta, free, eps):
    """What _discrepancy_tangent takes that does not depend on the direction, once per step: each site's velocity
    (long + i lat), force (2,), its rate (2, 2) and its shapes (2, NSK) at v+; each failed joint's shapes (NJK,)."""
    nsites = local.shape[0]
    u = np.zeros(nsites, dtype=np.complex128)
    force, rate, shapes = np.zeros((nsites, 2)), np.zeros((nsites, 2, 2)), np.zeros((nsites, 2, NSK))
    for s in range(nsites):
        g = SITE_GROUP[s]
        if g < 0:
            continue
        for a in range(v_plus.shape[0]):
            u[s] += local[s, a] * v_plus[a]
        force[s], rate[s] = site_force(u[s].real, u[s].imag, theta[g * NSK : (g + 1) * NSK], eps)
        shapes[s] = site_shapes(u[s].real, u[s].imag, eps)
    joints = np.zeros((free.shape[0], NJK))  # bias and spring at the step's start, drag and dry at v+
    for j in range(free.shape[0]):
        if free[j]:
            joints[j] = joint_shapes(x[3 + j], v_plus[3 + j], JOINT_EPS_RAD_S)
    return u, force, rate, shapes, joints


@jit
def _discrepancy_tangent(local, dlocal, v_plus, dx, theta, dtheta, free, terms):
    """The discrepancy force's change (discrepancy.py) at fixed v+ along one direction: the sites' Jacobians move
    with the state (dlocal), the coefficients by dtheta; in failed joints the bias and spring (at the step's
    start) move with the angle too (`terms`: _discrepancy_terms). Its change with v+ is in the Newton matrix
    (friction.assemble_step)."""
    u, force, rate, shapes, joints = terms
    nv = v_plus.shape[0]
    out = np.zeros(nv)
    for s in range(local.shape[0]):
        g = SITE_GROUP[s]
        if g < 0:
            continue
        du = 0.0 + 0.0j
        for a in range(nv):
            du += dlocal[s, a] * v_plus[a]
        df_long = rate[s, 0, 0] * du.real + rate[s, 0, 1] * du.imag
        df_lat = rate[s, 1, 0] * du.real + rate[s, 1, 1] * du.imag
        for i in range(NSK):  # a loop, not a BLAS call per site and direction
            df_long += shapes[s, 0, i] * dtheta[g * NSK + i]
            df_lat += shapes[s, 1, i] * dtheta[g * NSK + i]
        for a in range(nv):
            out[a] += dlocal[s, a].real * force[s, 0] + dlocal[s, a].imag * force[s, 1] + local[s, a].real * df_long
            out[a] += local[s, a].imag * df_lat
    joint, djoint = theta[NUM_TERMS - NJK :], dtheta[NUM_TERMS - NJK :]
    for j in range(free.shape[0]):
        if free[j]:
            k = 3 + j
            out[k] += djoint @ joints[j] - joint[1] * dx[k]
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
    mass, yaw_inertia, com, gravity_xy, in_plane, lower, upper, locked, chain, _ = plant
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
