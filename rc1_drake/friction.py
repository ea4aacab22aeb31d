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
f(u) ~ -D(u_n) u with D = c + mu N / sqrt(u_n^2 + eps^2) and polishes with Newton steps. The plant's
own step then reproduces v+ up to what this prediction leaves out: the joint-limit impulses, which
the plant itself treats implicitly. A failed joint's viscous friction -c_joint q_dot is in the same
solve, so all five of the paper's friction coefficients are parameters of this one system.
tests/test_convergence.py shows that halving eps or the time step moves the result by less than 1%
of the distance travelled.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from .config import NUM_JOINTS, Friction
from .kinematics import ChainGeometry, _wheel_kinematics, jit

GRAVITY_M_S2 = 9.81


@jit
def smooth_sign(v, eps):
    """sgn(v) for eps = 0, else v / sqrt(v^2 + eps^2)."""
    if eps == 0.0:
        return np.sign(v)
    return v / np.sqrt(v * v + eps * eps)


@jit
def wheel_friction_forces(v_long, v_lat, mu_long, mu_lat, c_long, c_lat, normal_force, eps):
    """Longitudinal and lateral friction force on each wheel, in the wheel's frame (Eqs. 4-5).

    v_long, v_lat: the wheel centre's velocity along its rolling and lateral axes (m/s);
    normal_force: N per wheel (newtons); eps: sgn() smoothing (m/s). Returns (f_long, f_lat), N.
    """
    f_long = -(c_long * v_long + mu_long * normal_force * smooth_sign(v_long, eps))
    f_lat = -(c_lat * v_lat + mu_lat * normal_force * smooth_sign(v_lat, eps))
    return f_long, f_lat


@jit
def _damping(u, c, coulomb, eps):
    """Secant and tangent rates of f(u) = -(c u + coulomb sgn_eps(u)): f = -secant u, df/du = -tangent."""
    s = 1.0 / np.sqrt(u * u + eps * eps)
    return c + coulomb * s, c + coulomb * eps * eps * s * s * s


@jit
def _add_damping(matrix, jac_long, jac_lat, d_long, d_lat, dt):
    """matrix + dt (J_long^T diag(d_long) J_long + J_lat^T diag(d_lat) J_lat)."""
    out = matrix.copy()
    n = out.shape[0]
    for w in range(jac_long.shape[0]):
        for a in range(n):
            la = dt * d_long[w] * jac_long[w, a]
            ta = dt * d_lat[w] * jac_lat[w, a]
            for b in range(n):
                out[a, b] += la * jac_long[w, b] + ta * jac_lat[w, b]
    return out


@jit
def implicit_friction_force(jac_long, jac_lat, joint_damping, mass_matrix, momentum_free, v, dt, mu_long,
                            mu_lat, c_long, c_lat, normal_force, eps, newton_steps):
    """Generalized friction force of one backward-Euler step (module docstring).

    jac_long, jac_lat: (W, nv) wheel velocity Jacobians along the rolling and lateral axes;
    joint_damping: (nv,) viscous joint friction per coordinate (c_joint on failed joints, else 0);
    momentum_free: M v + dt * (every other generalized force); v: the velocity at the step's start.
    eps must be > 0: the implicit solve needs a finite damping rate at v = 0.
    """
    coulomb_long = mu_long * normal_force
    coulomb_lat = mu_lat * normal_force
    mass_damped = mass_matrix + dt * np.diag(joint_damping)
    d_long, _ = _damping(jac_long @ v, c_long, coulomb_long, eps)
    d_lat, _ = _damping(jac_lat @ v, c_lat, coulomb_lat, eps)
    v_next = np.linalg.solve(_add_damping(mass_damped, jac_long, jac_lat, d_long, d_lat, dt), momentum_free)
    for _ in range(newton_steps):
        u_long = jac_long @ v_next
        u_lat = jac_lat @ v_next
        f_long, f_lat = wheel_friction_forces(u_long, u_lat, mu_long, mu_lat, c_long, c_lat, normal_force, eps)
        residual = mass_damped @ v_next - momentum_free - dt * (jac_long.T @ f_long + jac_lat.T @ f_lat)
        _, t_long = _damping(u_long, c_long, coulomb_long, eps)
        _, t_lat = _damping(u_lat, c_lat, coulomb_lat, eps)
        v_next = v_next - np.linalg.solve(_add_damping(mass_damped, jac_long, jac_lat, t_long, t_lat, dt), residual)
    return (mass_matrix @ v_next - momentum_free) / dt


# Parameter layout of FrictionForces: the paper's five coefficients, eps, then per joint its state
# (0 working, 1 failed free: its viscous friction acts, 2 locked: the plant holds it, and the solve
# predicts so), then per wheel its normal force, then per wheel its toe angle (rad, counter-clockwise,
# added to the SDF's wheel yaw; 0 in the paper's model).
C_JOINT, MU_LAT, MU_LONG, C_LAT, C_LONG, EPS = range(6)
WORKING, FREE, LOCKED = 0.0, 1.0, 2.0
LOCKED_DAMPING = 1e4  # N m s/rad: in the prediction only, a locked joint barely moves
FAILED = slice(6, 6 + NUM_JOINTS)
PER_WHEEL = 6 + NUM_JOINTS


def normal_slice(num_wheels: int) -> slice:
    return slice(PER_WHEEL, PER_WHEEL + num_wheels)


def toe_slice(num_wheels: int) -> slice:
    return slice(PER_WHEEL + num_wheels, PER_WHEEL + 2 * num_wheels)


@jit
def _friction_step(x, other_force, mass_matrix, dt, params, newton_steps, joint_in_parent, joint_in_child,
                   wheel_module, wheel_offset, wheel_toe):
    nw = wheel_module.shape[0]
    toe = wheel_toe * np.exp(1j * params[PER_WHEEL + nw : PER_WHEEL + 2 * nw])
    _, direction, jacobian = _wheel_kinematics(x, joint_in_parent, joint_in_child, wheel_module, wheel_offset, toe)
    local = np.conj(direction).reshape(-1, 1) * jacobian  # rows: v_long + i v_lat of each wheel
    jac_long = np.ascontiguousarray(local.real)
    jac_lat = np.ascontiguousarray(local.imag)
    nv = x.shape[0] // 2
    v = np.ascontiguousarray(x[nv:])
    joint_damping = np.zeros(nv)
    state = params[FAILED]
    joint_damping[3:] = np.where(state == FREE, params[C_JOINT], np.where(state == LOCKED, LOCKED_DAMPING, 0.0))
    return implicit_friction_force(jac_long, jac_lat, joint_damping, mass_matrix, mass_matrix @ v + dt * other_force,
                                   v, dt, params[MU_LONG], params[MU_LAT], params[C_LONG], params[C_LAT],
                                   params[PER_WHEEL : PER_WHEEL + nw], params[EPS], newton_steps)


class FrictionForces(LeafSystem):
    """The model's friction as one generalized force on the planar plant, implicit in time:
    the wheels' (Eqs. 4-5) and the failed joints' viscous friction c_joint (section 3).

    Inputs `plant_state` [q; v] and `servo_torque` (13, what the servos apply this step); output
    `generalized_force` for the plant's applied_generalized_force port. The five coefficients, eps,
    which joints have failed and each wheel's normal force are numeric parameters: a run changes
    them in its context without rebuilding anything.
    """

    NEWTON_STEPS = 2

    def __init__(self, plant, geometry: ChainGeometry, friction: Friction, sgn_smoothing_m_s: float):
        super().__init__()
        self._plant = plant
        self._plant_context = plant.CreateDefaultContext()
        self._geometry = geometry.arrays
        self._dt = plant.time_step()
        nq = plant.num_positions()
        self._num_wheels = len(geometry.wheel_module)
        normal = geometry.module_mass[geometry.wheel_module] * GRAVITY_M_S2
        self._param_index = self.DeclareNumericParameter(
            BasicVector(np.concatenate([self.pack(friction, sgn_smoothing_m_s), np.zeros(NUM_JOINTS), normal,
                                        np.zeros(self._num_wheels)]))
        )
        self.DeclareVectorInputPort("plant_state", 2 * nq)
        self.DeclareVectorInputPort("servo_torque", NUM_JOINTS)
        self.DeclareVectorOutputPort("generalized_force", nq, self._calc_generalized_force)

    @staticmethod
    def pack(friction: Friction, sgn_smoothing_m_s: float) -> np.ndarray:
        return np.array([friction.c_joint, friction.mu_lat, friction.mu_long, friction.c_lat, friction.c_long,
                         sgn_smoothing_m_s])

    def parameters(self, context) -> np.ndarray:
        """The mutable parameter vector (layout above: C_JOINT .. EPS, FAILED, normals, toes) in `context`."""
        return context.get_mutable_numeric_parameter(self._param_index).get_mutable_value()

    def set_friction(self, context, friction: Friction, sgn_smoothing_m_s: float) -> None:
        if not sgn_smoothing_m_s > 0:
            raise ValueError("the implicit friction needs sgn_smoothing_m_s > 0")
        self.parameters(context)[: EPS + 1] = self.pack(friction, sgn_smoothing_m_s)

    def set_wheel_toe(self, context, toe_rad) -> None:
        """Yaw every wheel (or each, given W angles) by toe_rad from its SDF direction."""
        self.parameters(context)[toe_slice(self._num_wheels)] = toe_rad

    def _calc_generalized_force(self, context, output):
        x = self.get_input_port(0).Eval(context)
        plant, plant_context = self._plant, self._plant_context
        plant.SetPositionsAndVelocities(plant_context, x)
        other = -plant.CalcBiasTerm(plant_context)
        other[3:] += self.get_input_port(1).Eval(context)
        output.SetFromVector(
            _friction_step(x, other, plant.CalcMassMatrix(plant_context), self._dt,
                           context.get_numeric_parameter(self._param_index).get_value(), self.NEWTON_STEPS,
                           *self._geometry)
        )
