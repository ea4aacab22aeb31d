"""The chain's implicit step matrix in O(n): each module's 3 x 3 planar inertia and the joints' motions, and the
articulated-body solve (Featherstone's ABA, here as the block elimination of one linear system) that replaces the
dense assembly and Cholesky factor of friction.assemble_step in the implicit friction solve (paper Eqs. 1, 4-5).

A module's planar twist V = (vx, vy, w) is taken at the head's centre p0, in world axes; the head's twist is its
three base coordinates (x, y, yaw rates), and joint j adds S_j q_dot_j with S_j = (d_y, -d_x, 1), d = P_j - p0
(P_j: the joint's world position): the velocity a unit rotation about P_j gives the point at p0. The step matrix
of the backward-Euler step is then

    A = sum_k J_k^T B_k J_k + diag(a),   J_k = [I_3, S_0, ..., S_{k-1}, 0 ...]   (module k's twist = J_k v),

with B_k module k's planar inertia about p0 (mass m at centre of mass c, yaw inertia I about it:
m [[1, 0, -r_y], [0, 1, r_x], [-r_y, r_x, |r|^2]] + I e_3 e_3^T, r = c - p0) plus dt times each wheel's and drag
point's damping rate, P^T D P with P its velocity rows on the twist, and a the joints' own rates (their viscous
friction, dry friction's rate, the servos' backward-Euler rate). This is the mass matrix of engine/dynamics.py
(Eq. 1) with the friction's rate added body by body: every wheel term is local to its module, as an inertia is.
"""

from __future__ import annotations

import numpy as np

from .kinematics import jit


@jit
def chain_inertias(frames, bodies):
    """(B (nm, 3, 3): each module's planar inertia about the head's centre, world axes; S (nj, 3): the joints'
    motions) from the chain's frames (kinematics.chain_frames). bodies (nm, 4): mass, yaw inertia about the centre
    of mass, centre of mass (x, y) in the module's frame (module docstring)."""
    e, p, joint = frames
    nm = p.shape[0]
    inertia = np.zeros((nm, 3, 3))
    motion = np.empty((nm - 1, 3))
    for k in range(nm):
        if k > 0:
            d = joint[k - 1] - p[0]
            motion[k - 1, 0], motion[k - 1, 1], motion[k - 1, 2] = d.imag, -d.real, 1.0
        r = p[k] + e[k] * (bodies[k, 2] + 1j * bodies[k, 3]) - p[0]
        m = bodies[k, 0]
        inertia[k, 0, 0] = m
        inertia[k, 1, 1] = m
        inertia[k, 0, 2] = inertia[k, 2, 0] = -m * r.imag
        inertia[k, 1, 2] = inertia[k, 2, 1] = m * r.real
        inertia[k, 2, 2] = m * (r.real**2 + r.imag**2) + bodies[k, 1]
    return inertia, motion


@jit
def add_point_rate(inertia, rows, rate):
    """inertia += rows^T rate rows in place: a point's damping (rate, r x r) on its module's twist, rows (r, 3) its
    velocity per unit twist (the first three columns of its velocity Jacobian)."""
    n = rows.shape[0]
    for a in range(3):
        for b in range(3):
            total = 0.0
            for i in range(n):
                for j in range(n):
                    total += rows[i, a] * rate[i, j] * rows[j, b]
            inertia[a, b] += total


@jit
def articulated_solve(inertia, joint_rate, motion, rhs):
    """A^-1 rhs for A = sum_k J_k^T inertia_k J_k + diag(joint_rate) (module docstring) by the articulated-body
    recursion: from the tail, each joint's subtree is folded into its parent's inertia; the head's 3 x 3 is solved;
    then the joints' rates follow from the head outward. An empty array where a pivot is not positive (A is not
    definite): the caller then solves densely."""
    nj = motion.shape[0]
    nv = rhs.shape[0]
    art = inertia.copy()
    # One scratch array, not four: per joint j, the bias force of its subtree (columns 0-2, j = nj: none),
    # U_j = art_{j+1} S_j (3-5), the pivot S_j . U_j + rate (6) and rhs_j - S_j . bias_{j+1} (7).
    work = np.zeros((nj + 1, 8))
    for j in range(nj - 1, -1, -1):  # loops, not BLAS calls: 3 x 3 blocks
        d = joint_rate[3 + j]
        r = rhs[3 + j]
        for a in range(3):
            u = art[j + 1, a, 0] * motion[j, 0] + art[j + 1, a, 1] * motion[j, 1] + art[j + 1, a, 2] * motion[j, 2]
            work[j, 3 + a] = u
            d += motion[j, a] * u
            r -= motion[j, a] * work[j + 1, a]
        if not d > 0.0:
            return np.zeros(0)
        work[j, 6], work[j, 7] = d, r
        for a in range(3):
            w = work[j, 3 + a] / d  # one division a row: a division costs several products
            work[j, a] += work[j + 1, a] + w * r
            for b in range(3):
                art[j, a, b] += art[j + 1, a, b] - w * work[j, 3 + b]
    head = art[0]  # the fold's own copy: the head's 3 x 3 with its rates, in place
    for a in range(3):
        head[a, a] += joint_rate[a]
    # The head's 3 x 3 by Cholesky, written out: a generic call costs more than the whole recursion.
    l00 = head[0, 0]
    if not l00 > 0.0:
        return np.zeros(0)
    l00 = np.sqrt(l00)
    l10, l20 = head[1, 0] / l00, head[2, 0] / l00
    l11 = head[1, 1] - l10 * l10
    if not l11 > 0.0:
        return np.zeros(0)
    l11 = np.sqrt(l11)
    l21 = (head[2, 1] - l20 * l10) / l11
    l22 = head[2, 2] - l20 * l20 - l21 * l21
    if not l22 > 0.0:
        return np.zeros(0)
    l22 = np.sqrt(l22)
    y0 = (rhs[0] - work[0, 0]) / l00
    y1 = (rhs[1] - work[0, 1] - l10 * y0) / l11
    y2 = (rhs[2] - work[0, 2] - l20 * y0 - l21 * y1) / l22
    out = np.empty(nv)
    out[2] = y2 / l22
    out[1] = (y1 - l21 * out[2]) / l11
    out[0] = (y0 - l10 * out[1] - l20 * out[2]) / l00
    t0, t1, t2 = out[0], out[1], out[2]  # the parent's twist
    for j in range(nj):
        rate = (work[j, 7] - work[j, 3] * t0 - work[j, 4] * t1 - work[j, 5] * t2) / work[j, 6]
        out[3 + j] = rate
        t0, t1, t2 = t0 + motion[j, 0] * rate, t1 + motion[j, 1] * rate, t2 + motion[j, 2] * rate
    return out


@jit
def articulated_matrix(inertia, joint_rate, motion):
    """A = sum_k J_k^T inertia_k J_k + diag(joint_rate), dense (module docstring): where the recursion finds A not
    definite, and to check it."""
    nj = motion.shape[0]
    nv = nj + 3
    columns = np.zeros((3, nv))  # J_k, grown one joint a module
    columns[0, 0] = columns[1, 1] = columns[2, 2] = 1.0
    out = np.diag(joint_rate.astype(np.float64))
    for k in range(nj + 1):
        if k > 0:
            columns[:, 2 + k] = motion[k - 1]
        n = 3 + k
        used = np.ascontiguousarray(columns[:, :n])
        out[:n, :n] += used.T @ (np.ascontiguousarray(inertia[k]) @ used)
    return out
