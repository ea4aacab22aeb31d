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

from ..kinematics import ChainGeometry, jit


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
def chain_terms(x, mass, yaw_inertia, com, joint_in_parent, joint_in_child, gravity_xy):
    """(M, C v, g) of the planar chain at state x (module docstring)."""
    nj = joint_in_parent.shape[0]
    nm = nj + 1
    nv = nj + 3
    phi = np.cumsum(x[2:nv])
    phi_dot = np.cumsum(x[nv + 2 :])
    e = np.exp(1j * phi)
    p = np.empty(nm, dtype=np.complex128)  # module origins
    acc = np.empty(nm, dtype=np.complex128)  # their velocity-product accelerations
    joint_xy = np.empty(nj, dtype=np.complex128)
    p[0] = x[0] + 1j * x[1]
    acc[0] = 0.0
    for j in range(nj):
        a = e[j] * joint_in_parent[j]
        b = e[j + 1] * joint_in_child[j]
        joint_xy[j] = p[j] + a
        p[j + 1] = p[j] + a - b
        acc[j + 1] = acc[j] - phi_dot[j] ** 2 * a + phi_dot[j + 1] ** 2 * b
    M = np.zeros((nv, nv))
    bias = np.zeros(nv)
    gravity = np.zeros(nv)
    jac = np.empty(nv, dtype=np.complex128)
    for k in range(nm):
        r = e[k] * com[k]
        c = p[k] + r
        a_k = acc[k] - phi_dot[k] ** 2 * r
        n = 3 + k  # coordinates that move module k: x, y, yaw and the k joints ahead of it
        jac[0] = 1.0
        jac[1] = 1j
        jac[2] = 1j * (c - p[0])
        for j in range(k):
            jac[3 + j] = 1j * (c - joint_xy[j])
        m = mass[k]
        for i in range(n):
            ci = np.conj(jac[i])
            bias[i] += m * (ci * a_k).real
            gravity[i] += m * (ci * gravity_xy).real
            for j in range(i, n):
                M[i, j] += m * (ci * jac[j]).real
        for i in range(2, n):  # Omega_k: the head yaw and joints 0..k-1
            for j in range(i, n):
                M[i, j] += yaw_inertia[k]
    for i in range(nv):
        for j in range(i):
            M[i, j] = M[j, i]
    return M, bias, gravity
