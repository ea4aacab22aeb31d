"""The planar chain's rigid-body terms of paper Eq. 1, M(q) v_dot + C(q, v) v = tau, as compiled kernels.

The numbers (masses, yaw inertias, centres of mass, joint and wheel locations, limits, effort) are read
once from the MultibodyPlant that `models/rc1.sdf` makes, so the SDF stays the single source of the
robot's numbers; tests/test_engine.py checks these terms against `plant.CalcMassMatrix`,
`CalcBiasTerm` and `CalcGravityGeneralizedForces` on random states.

Module k's centre of mass c_k moves at c_dot_k = J_k v (J_k: a complex row, see kinematics.py) and turns
at w_k = Omega_k v (Omega_k = 1 on the head yaw and on the joints ahead of module k). Then

    M = sum_k m_k Re(J_k^H J_k) + I_k Omega_k^T Omega_k,
    C v = sum_k m_k Re(J_k^H a_k),   a_k = c_ddot_k at v_dot = 0 (the velocity-product acceleration),
    g = sum_k m_k Re(J_k^H (g_x + i g_y))   (gravity's generalized force; zero on a level floor),

with a_k from the chain p_{k+1} = p_k + R(phi_k) a - R(phi_{k+1}) b differentiated twice at phi_ddot = 0.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..kinematics import ChainGeometry, chain_frames, jit


@dataclasses.dataclass(frozen=True)
class PlantNumbers:
    """What the compiled engine takes from the MultibodyPlant (SI units)."""

    geometry: ChainGeometry
    com: np.ndarray  # (14,) complex: each module's centre of mass in its frame
    central_yaw_inertia: np.ndarray  # (14,) kg m^2 about each module's centre of mass
    effort_limit: np.ndarray  # (13,) N m: the SDF's, the servos' power (servo.py)
    lower_limit: np.ndarray  # (13,) rad
    upper_limit: np.ndarray  # (13,) rad

    def masses(self, payload_module: int = 0, payload_kg: float = 0.0) -> np.ndarray:
        """Module masses with a payload (a point mass at module `payload_module`'s centre, 1-based; 0: none)."""
        mass = np.array(self.geometry.module_mass, dtype=float)
        if payload_module:
            mass[payload_module - 1] += payload_kg
        return mass


@functools.lru_cache(maxsize=1)
def plant_numbers() -> PlantNumbers:
    """The robot's numbers as the MultibodyPlant reads them from models/rc1.sdf (once per process)."""
    from pydrake.systems.framework import DiagramBuilder

    from ..model import add_rc1_plant, module_inertias

    rc1 = add_rc1_plant(DiagramBuilder(), time_step=1e-3)
    plant = rc1.plant
    bodies = module_inertias(plant, plant.CreateDefaultContext())
    return PlantNumbers(
        geometry=rc1.geometry,
        com=bodies[:, 2] + 1j * bodies[:, 3],
        central_yaw_inertia=bodies[:, 1],
        effort_limit=np.array(rc1.effort_limit, dtype=float),
        lower_limit=np.array([j.position_lower_limits()[0] for j in rc1.joints]),
        upper_limit=np.array([j.position_upper_limits()[0] for j in rc1.joints]),
    )


@jit
def chain_terms(x, mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy, frames=None):
    """(M, C v, g) of the planar chain at state x (module docstring), by composite bodies: every column of J_k is
    a planar twist S_j about the head's centre (the head's x, y, yaw; joint j's, which moves modules j + 1 on), so
    M_ij = S_i . (sum over the modules column j moves of B_k) S_j for i <= j, and C v, g are the columns' S_i
    against the force sums: O(n^2), not the O(n^3) of summing module by module. `frames`: the chain's frames at x
    (kinematics.chain_frames), when the caller has them (a step: the friction solve takes them too)."""
    nj = joint_in_parent.shape[0]
    nm = nj + 1
    nv = nj + 3
    if frames is None:
        e, p, joint_xy = chain_frames(x, joint_in_parent, joint_in_child)
    else:
        e, p, joint_xy = frames
    phi_dot = np.empty(nm)
    acc = np.empty(nm, dtype=np.complex128)  # the module origins' velocity-product accelerations
    acc[0] = 0.0
    for k in range(nm):
        phi_dot[k] = x[nv + 2 + k] + (phi_dot[k - 1] if k > 0 else 0.0)
        if k > 0:
            j = k - 1
            a, b = e[j] * joint_in_parent[j], e[k] * joint_in_child[j]
            acc[k] = acc[j] - phi_dot[j] ** 2 * a + phi_dot[k] ** 2 * b
    # Per column: its twist (vx, vy, w at the head's centre), then the composite sums of the bodies it moves:
    # mass, first moment about the head's centre, yaw inertia about it, and the velocity-product and gravity
    # forces (x, y, torque about the head's centre).
    twist = np.zeros((nv, 3))
    twist[0, 0] = twist[1, 1] = twist[2, 2] = 1.0
    for j in range(nj):
        d = joint_xy[j] - p[0]
        twist[3 + j, 0], twist[3 + j, 1], twist[3 + j, 2] = d.imag, -d.real, 1.0
    body = np.zeros((nm, 10))  # m, m r_x, m r_y, yaw inertia about the head's centre, C-force (3), g-force (3)
    for k in range(nm - 1, -1, -1):
        r = e[k] * com[k]
        u = p[k] + r - p[0]
        m = mass[k]
        a_k = m * (acc[k] - phi_dot[k] ** 2 * r)
        g_k = m * gravity_xy
        b = body[k]
        b[0], b[1], b[2], b[3] = m, m * u.real, m * u.imag, m * (u.real**2 + u.imag**2) + yaw_inertia[k]
        b[4], b[5], b[6] = a_k.real, a_k.imag, u.real * a_k.imag - u.imag * a_k.real
        b[7], b[8], b[9] = g_k.real, g_k.imag, u.real * g_k.imag - u.imag * g_k.real
        if k + 1 < nm:
            for c in range(10):
                b[c] += body[k + 1, c]
    M = np.empty((nv, nv))
    bias = np.empty(nv)
    gravity = np.empty(nv)
    for j in range(nv):
        o = 0 if j < 3 else j - 2  # the first module column j moves
        m, sx, sy, yaw = body[o, 0], body[o, 1], body[o, 2], body[o, 3]
        s0, s1, s2 = twist[j, 0], twist[j, 1], twist[j, 2]
        f0, f1, f2 = m * s0 - sy * s2, m * s1 + sx * s2, -sy * s0 + sx * s1 + yaw * s2
        for i in range(j + 1):
            M[i, j] = M[j, i] = twist[i, 0] * f0 + twist[i, 1] * f1 + twist[i, 2] * f2
        bias[j] = s0 * body[o, 4] + s1 * body[o, 5] + s2 * body[o, 6]
        gravity[j] = s0 * body[o, 7] + s1 * body[o, 8] + s2 * body[o, 9]
    return M, bias, gravity
