"""An independent implementation of the planar equations of motion (paper Eq. 1), for checking Drake.

It shares no code with the Drake model beyond the geometry numbers (module length, masses, wheel
places): kinematics in real 2-vectors, the mass matrix and Coriolis terms from the module Jacobians
(Lagrange's equations for the 14 rigid modules, which is Eq. 1 written in relative joint angles),
wheel friction from Eqs. 4-5, and SciPy's stiff ODE solver. As in the paper, the working joints are
prescribed: they follow the serpenoid exactly, with no servo. A failed joint is free, with viscous
friction c_joint and a stiff PD restoring torque beyond +-38 deg (paper section 3).

Forces outside the paper's model, for data that hide them (issue 43): a tether dragging the tail's end, the
discrepancy model's terms (the sites, groups and shapes that rc1_drake/discrepancy.py states), written anew here
from their definitions, and a floor seam twisting the head at a fixed x (in no other model: what discovery makes of
a shape its library lacks), read from the scenario's effect keys (HiddenForces).

    M(z) z_ddot = -sum_k m_k J_k^T h_k(z, z_dot) + sum_w J_w^T F_w + tau_joint

with z = (x, y, yaw of the head, q_1..q_13), J_k the Jacobian of module k's centre, h_k its
velocity-product acceleration, F_w the wheel forces of Eqs. 4-5. Rows of the working joints are
dropped; their accelerations are known.
"""

from __future__ import annotations

import dataclasses
import math
import re
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from .config import Scenario
from .gait import serpenoid_parameters

STOP_GAIN = 200.0  # N m/rad, the joint-limit PD's stiffness (paper section 3)
STOP_DAMPING = 1.0  # N m s/rad, its damping, active beyond the limit
LIMIT_RAD = math.radians(38.0)
G = 9.81
TETHER_EPS_M_S = 0.05  # the tether's sgn() smoothing, as the engines': a cable's drag builds up over a few cm/s
JOINT_EPS_RAD_S = 0.01  # a failed joint's dry torque's sgn() smoothing, as the engines'
# The discrepancy model's site groups by 0-based module (the head's centre; wheels of modules 2-5, 6-10, 11-14; the
# tail's end), and its kinds: in the module's frame at the site's velocity (u_long toward the head, u_lat to the
# module's left), a positive drag or dry coefficient resisting the motion.
WHEEL_GROUPS = {"front": range(1, 5), "middle": range(5, 10), "rear": range(10, 14)}
SITE_KINDS = (
    "drag_long", "drag_lat", "dry_long", "dry_lat", "side_by_long", "push_long", "push_lat", "quad_long", "quad_lat"
)  # fmt: skip
JOINT_KINDS = ("bias", "spring", "drag", "dry")
SEAM_WIDTH_M = 0.03  # a floor seam's reach along x (the standard deviation of its Gaussian profile)


@dataclasses.dataclass
class HiddenForces:
    """What the scenario's effects add beyond Eqs. 4-5: a tether's Coulomb pull at the tail's end (N) and the
    discrepancy terms, {group: {kind: coefficient}} at sites and {kind: coefficient} in the failed joints."""

    tether_N: float = 0.0
    sites: dict = dataclasses.field(default_factory=dict)
    joint: dict = dataclasses.field(default_factory=dict)
    seam_Nm: float = 0.0  # a floor seam: a torque turning the head counter-clockwise as its centre crosses seam_x_m
    seam_x_m: float = 0.3
    stop_gain: float = STOP_GAIN  # a failed joint's stop beyond +-38 deg: another stop's form (issue 67)
    stop_damping: float = STOP_DAMPING

    @classmethod
    def from_effects(cls, effects: dict) -> HiddenForces:
        """The forces of `effects`' keys tail_tether_N, floor_seam_Nm and floor_seam_x_m, reference_stop_Nm_per_rad
        and reference_stop_Nm_s_per_rad (the failed joints' PD stop beyond the limit), and
        discrepancy_<group>_<kind>_<unit>; other keys are not forces (the toe is toe_rad; the sensor faults act on
        the command and the readings)."""
        out = cls(
            tether_N=float(effects.get("tail_tether_N", 0.0)),
            seam_Nm=float(effects.get("floor_seam_Nm", 0.0)),
            seam_x_m=float(effects.get("floor_seam_x_m", cls.seam_x_m)),
            stop_gain=float(effects.get("reference_stop_Nm_per_rad", STOP_GAIN)),
            stop_damping=float(effects.get("reference_stop_Nm_s_per_rad", STOP_DAMPING)),
        )
        if out.stop_gain <= 0.0 or out.stop_damping < 0.0:
            raise ValueError(
                f"reference: the failed joint's stop needs a gain > 0 and a damping >= 0, got "
                f"{out.stop_gain} N m/rad and {out.stop_damping} N m s/rad"
            )
        for key, value in effects.items():
            found = re.fullmatch(r"discrepancy_(head|front|middle|rear|tail|failed_joint)_([a-z_]+?)_(N|Nm)\w*", key)
            if not found:
                if key.startswith("discrepancy_"):
                    raise ValueError(f"reference: unknown discrepancy term {key!r}")
                continue
            group, kind = found.group(1), found.group(2)
            if kind not in (JOINT_KINDS if group == "failed_joint" else SITE_KINDS):
                raise ValueError(f"reference: unknown discrepancy term {key!r}")
            where = out.joint if group == "failed_joint" else out.sites.setdefault(group, {})
            where[kind] = float(value)
        return out

    def __bool__(self) -> bool:
        return bool(self.tether_N or self.sites or self.joint or self.seam_Nm)

    def stop_torque(self, q, qd) -> np.ndarray:
        """The failed joints' limit torques at angles q and rates qd (arrays): the paper's PD beyond +-38 deg
        (section 3), with this truth's gain and damping."""
        over = np.abs(q) - LIMIT_RAD
        return np.where(over > 0, -np.sign(q) * self.stop_gain * over - self.stop_damping * qd, 0.0)

    def seam_torque(self, head_x) -> float:
        """The seam's torque on the head (N m, counter-clockwise) with its centre at x = head_x."""
        return self.seam_Nm * math.exp(-0.5 * ((head_x - self.seam_x_m) / SEAM_WIDTH_M) ** 2)

    def joint_torque(self, q, qd) -> np.ndarray:
        """The failed joints' torques at angles q and rates qd (arrays)."""
        c = self.joint.get
        sgn = qd / np.sqrt(qd * qd + JOINT_EPS_RAD_S**2)
        return c("bias", 0.0) - c("spring", 0.0) * q - c("drag", 0.0) * qd - c("dry", 0.0) * sgn


def site_law(c: dict, u_long, u_lat, eps) -> tuple:
    """A site's force (f_long, f_lat) in its module's frame for its group's coefficients `c` (kind -> value)."""
    k = lambda kind: c.get(kind, 0.0)  # noqa: E731
    f_long = (
        -k("drag_long") * u_long
        - k("dry_long") * u_long / np.sqrt(u_long * u_long + eps * eps)
        + k("push_long")
        - k("quad_long") * np.abs(u_long) * u_long
    )
    f_lat = (
        -k("drag_lat") * u_lat
        - k("dry_lat") * u_lat / np.sqrt(u_lat * u_lat + eps * eps)
        + k("side_by_long") * u_long
        + k("push_lat")
        - k("quad_lat") * np.abs(u_lat) * u_lat
    )
    return f_long, f_lat


@dataclasses.dataclass
class ReferenceRun:
    t: np.ndarray
    head_xy: np.ndarray  # (N, 2)
    head_yaw: np.ndarray
    q: np.ndarray  # (N, 13)
    crossed: bool
    wall_time_s: float
    circled: bool = False  # stopped where the head's yaw had turned by the stop's revolutions
    z_dot: np.ndarray | None = None  # (N, 16) rates of (x, y, yaw of the head, q_1..q_13)
    joint_torque: np.ndarray | None = None  # (N, 13) N m the working joints took to follow their path (0: failed)


class PlanarSnake:
    """The planar chain with real-vector kinematics; positions of module centres from (x, y, yaw, q)."""

    def __init__(self, geometry):
        real = lambda c: np.stack([np.real(c), np.imag(c)], axis=-1)  # noqa: E731
        self.a = real(geometry.joint_in_parent)  # (13, 2)
        self.b = real(geometry.joint_in_child)
        self.wheel_module = np.asarray(geometry.wheel_module)
        self.wheel_offset = real(geometry.wheel_offset)
        self.wheel_yaw = np.asarray(geometry.wheel_yaw, dtype=float)
        self.mass = np.asarray(geometry.module_mass, dtype=float)
        self.inertia = np.asarray(geometry.module_yaw_inertia, dtype=float)
        self.n = len(self.mass)

    @staticmethod
    def _rot(phi, v):
        c, s = np.cos(phi), np.sin(phi)
        return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)

    def frames(self, z):
        """Module yaws (14,), centres (14, 2) and joint positions (13, 2) in the world."""
        phi = z[2] + np.concatenate([[0.0], np.cumsum(z[3:])])
        ra = self._rot(phi[:-1], self.a)
        rb = self._rot(phi[1:], self.b)
        centres = z[None, 0:2] + np.concatenate([np.zeros((1, 2)), np.cumsum(ra - rb, axis=0)])
        joints = centres[:-1] + ra
        return phi, centres, joints

    def point_jacobian(self, points, modules, centres, joints):
        """(P, 2, 16) Jacobian of world points fixed on the given modules."""
        P = len(points)
        jac = np.zeros((P, 2, 3 + self.n - 1))
        jac[:, 0, 0] = 1.0
        jac[:, 1, 1] = 1.0
        rel = points - centres[0]
        jac[:, 0, 2], jac[:, 1, 2] = -rel[:, 1], rel[:, 0]
        for j in range(self.n - 1):
            behind = modules > j
            rel = points[behind] - joints[j]
            jac[behind, 0, 3 + j] = -rel[:, 1]
            jac[behind, 1, 3 + j] = rel[:, 0]
        return jac

    def dynamics_terms(self, z, zd):
        """Mass matrix M(z) and the velocity-product force -sum m J^T h."""
        phi, centres, joints = self.frames(z)
        phid = zd[2] + np.concatenate([[0.0], np.cumsum(zd[3:])])
        jac = self.point_jacobian(centres, np.arange(self.n), centres, joints)
        rot = np.zeros((self.n, 3 + self.n - 1))  # d(phi_k)/dz
        rot[:, 2] = 1.0
        for k in range(1, self.n):
            rot[k, 3 : 3 + k] = 1.0
        mass_matrix = np.einsum("k,kai,kaj->ij", self.mass, jac, jac) + np.einsum("k,ki,kj->ij", self.inertia, rot, rot)
        # Centripetal acceleration of each centre: differentiate the chain twice, keep the phid^2 terms.
        ra = self._rot(phi[:-1], self.a)
        rb = self._rot(phi[1:], self.b)
        steps = -(phid[:-1, None] ** 2) * ra + (phid[1:, None] ** 2) * rb
        h = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
        return mass_matrix, -np.einsum("k,kai,ka->i", self.mass, jac, h)

    def wheel_force(self, z, zd, friction, eps, toe_rad=0.0):
        """Generalized force of Eqs. 4-5 on all wheels (each turned by toe_rad, counter-clockwise)."""
        phi, centres, joints = self.frames(z)
        m = self.wheel_module
        points = centres[m] + self._rot(phi[m], self.wheel_offset)
        jac = self.point_jacobian(points, m, centres, joints)
        vel = jac @ zd
        heading = phi[m] + self.wheel_yaw + toe_rad
        t = np.stack([np.cos(heading), np.sin(heading)], axis=-1)
        n = np.stack([-t[:, 1], t[:, 0]], axis=-1)
        v_long = (vel * t).sum(axis=1)
        v_lat = (vel * n).sum(axis=1)
        weight = self.mass[m] * G
        sgn = lambda v: v / np.sqrt(v * v + eps * eps)  # noqa: E731
        f_long = -(friction.c_long * v_long + friction.mu_long * weight * sgn(v_long))
        f_lat = -(friction.c_lat * v_lat + friction.mu_lat * weight * sgn(v_lat))
        forces = f_long[:, None] * t + f_lat[:, None] * n
        return np.einsum("pai,pa->i", jac, forces)

    def hidden_force(self, z, zd, hidden: HiddenForces, eps) -> np.ndarray:
        """Generalized force of the tether and the discrepancy terms at their sites (HiddenForces; the failed
        joints' torques are the caller's: it knows which joints are free)."""
        phi, centres, joints = self.frames(z)
        out = np.zeros_like(zd)
        tail = self.n - 1
        tail_end = centres[tail] - self._rot(phi[tail], self.b[-1])
        sites = []  # (module, world point, coefficients)
        if "head" in hidden.sites:
            sites.append((0, centres[0], hidden.sites["head"]))
        for w, m in enumerate(self.wheel_module):
            group = next((g for g, ms in WHEEL_GROUPS.items() if m in ms), None)
            if group in hidden.sites:
                sites.append((m, centres[m] + self._rot(phi[m], self.wheel_offset[w]), hidden.sites[group]))
        if "tail" in hidden.sites:
            sites.append((tail, tail_end, hidden.sites["tail"]))
        for m, point, c in sites:
            jac = self.point_jacobian(point[None], np.array([m]), centres, joints)[0]
            t = np.array([math.cos(phi[m]), math.sin(phi[m])])
            n = np.array([-t[1], t[0]])
            vel = jac @ zd
            f_long, f_lat = site_law(c, vel @ t, vel @ n, eps)
            out += jac.T @ (f_long * t + f_lat * n)
        if hidden.tether_N:
            jac = self.point_jacobian(tail_end[None], np.array([tail]), centres, joints)[0]
            vel = jac @ zd
            out += jac.T @ (-hidden.tether_N * vel / math.sqrt(vel @ vel + TETHER_EPS_M_S**2))
        out[2] += hidden.seam_torque(z[0])  # a torque on the head alone does work on its yaw only
        return out


def _prescribed(gait, joint_path):
    """The working joints' (q, q_dot, q_ddot) at t: the gait's serpenoid, or a cubic spline through joint_path."""
    if joint_path is None:
        amp, omega, phase, bias = serpenoid_parameters(gait)

        def serpenoid(t):
            arg = omega * t - phase
            return (amp * np.sin(arg) + bias, amp * omega * np.cos(arg), -amp * omega**2 * np.sin(arg))

        return serpenoid
    spline = CubicSpline(joint_path[0], joint_path[1], axis=0)
    d1, d2 = spline.derivative(1), spline.derivative(2)

    def splined(t):
        return spline(t), d1(t), d2(t)

    return splined


def _start_state(snake, scenario, prescribed, free, at_rest):
    """The free coordinates and rates at t = 0 as the protocol says: serpenoid angles and rates, head at the start
    point, mean module yaw along the heading and not turning, the centre of mass (or the head) at rest."""
    q0, qd0, _ = prescribed(0.0)
    rel = np.concatenate([[0.0], np.cumsum(q0)])
    reld = np.concatenate([[0.0], np.cumsum(qd0)])
    z0 = np.concatenate(
        [[scenario.start.x_m, scenario.start.y_m, math.radians(scenario.start.heading_deg) - rel.mean()], q0]
    )
    zd0 = np.concatenate([[0.0, 0.0, -reld.mean()], qd0])
    _, centres, joints = snake.frames(z0)
    if at_rest == "centre":
        jac = snake.point_jacobian(centres, np.arange(snake.n), centres, joints)
        zd0[0:2] -= np.einsum("k,kai,i->a", snake.mass, jac, zd0) / snake.mass.sum()
    elif at_rest != "head":
        raise ValueError(f"at_rest must be 'centre' or 'head', got {at_rest!r}")
    return np.concatenate([z0[free], zd0[free]])


def _stop_events(scenario, y0) -> list:
    """solve_ivp's terminal events: the head crossing the line, its yaw turned by the revolutions (either way)."""
    events = []
    line = scenario.stop.line_x_m
    if line is not None:

        def crossed(t, y):
            return y[0] - line

        crossed.terminal, crossed.direction = True, 1
        events.append(crossed)
    if scenario.stop.revolutions is not None:  # the head's yaw has turned by the revolutions, either way
        turn, yaw0 = 2 * math.pi * scenario.stop.revolutions, y0[2]

        def circled(t, y):
            return abs(y[2] - yaw0) - turn

        circled.terminal, circled.direction = True, 1
        events.append(circled)
    return events


def simulate_reference(
    scenario: Scenario, geometry, *, joint_path=None, rtol=1e-7, atol=1e-9, at_rest="centre", t_eval=None, toe_rad=0.0
) -> ReferenceRun:
    """Integrate the scenario with the working joints prescribed; stops at the line or time limit.

    The working joints follow the serpenoid of the scenario's gait, or, if joint_path = (t, q) is
    given (q: (N, 13) rad), a cubic spline through those samples (e.g. the angles a servo achieved).
    At t = 0 the mean module yaw does not turn and the body's centre of mass (at_rest="centre", the protocol's
    start) or the head (at_rest="head") is at rest. `t_eval`: the output times (the solver's own by default; a
    line crossing is appended as the last sample); toe_rad: every wheel turned by it (the wheel_toe effect). The
    scenario's tether and discrepancy terms act as HiddenForces.
    """
    if any(f.time_s != 0.0 or f.mode != "free" for f in scenario.failures):
        raise ValueError("the reference model handles joints that are free from t = 0 only")
    snake = PlanarSnake(geometry)
    failed = np.array(sorted(f.joint - 1 for f in scenario.failures), dtype=int)
    working = np.setdiff1d(np.arange(snake.n - 1), failed)
    free = np.concatenate([[0, 1, 2], 3 + failed])
    fixed = 3 + working
    eps = scenario.numerics.sgn_smoothing_m_s
    c_joint = scenario.friction.c_joint
    hidden = HiddenForces.from_effects(scenario.effects)

    prescribed = _prescribed(scenario.gait, joint_path)

    def full(t, y):
        q, qd, qdd = prescribed(t)
        z = np.empty(3 + snake.n - 1)
        zd = np.empty_like(z)
        z[fixed], zd[fixed] = q[working], qd[working]
        nf = len(free)
        z[free], zd[free] = y[:nf], y[nf:]
        return z, zd, qdd

    def dynamics(t, y):
        """The free coordinates' accelerations, and the generalized accelerations, masses and forces."""
        z, zd, qdd = full(t, y)
        mass_matrix, velocity_force = snake.dynamics_terms(z, zd)
        force = velocity_force + snake.wheel_force(z, zd, scenario.friction, eps, toe_rad)
        qf, qfd = z[3 + failed], zd[3 + failed]
        force[3 + failed] += -c_joint * qfd + hidden.stop_torque(qf, qfd)
        if hidden:
            force += snake.hidden_force(z, zd, hidden, eps)
            force[3 + failed] += hidden.joint_torque(qf, qfd)
        rhs_free = force[free] - mass_matrix[np.ix_(free, fixed)] @ qdd[working]
        acc = np.linalg.solve(mass_matrix[np.ix_(free, free)], rhs_free)
        zdd = np.empty_like(z)
        zdd[free], zdd[fixed] = acc, qdd[working]
        return zd[free], acc, zdd, mass_matrix, force

    def rhs(t, y):
        rates, acc, *_ = dynamics(t, y)
        return np.concatenate([rates, acc])

    def working_torque(t, y):
        """The torque each working joint takes to follow its path (Eq. 1's rows of the prescribed joints)."""
        _, _, zdd, mass_matrix, force = dynamics(t, y)
        tau = (mass_matrix @ zdd - force)[3:]
        tau[failed] = 0.0
        return tau

    y0 = _start_state(snake, scenario, prescribed, free, at_rest)
    events = _stop_events(scenario, y0)
    start = time.perf_counter()
    sol = solve_ivp(
        rhs,
        (0.0, scenario.stop.time_limit_s),
        y0,
        method="LSODA",
        rtol=rtol,
        atol=atol,
        events=events,
        dense_output=False,
        max_step=0.01,
        t_eval=t_eval,
    )
    wall = time.perf_counter() - start
    if not sol.success:
        raise RuntimeError(f"reference integration failed: {sol.message}")
    fired = [k for k, e in enumerate(sol.t_events or []) if len(e)]
    crossed = bool(fired) and events[fired[0]].__name__ == "crossed"
    times, states = sol.t, sol.y.T
    if fired and t_eval is not None:
        times = np.append(times, sol.t_events[fired[0]][0])
        states = np.vstack([states, sol.y_events[fired[0]][0]])
    motion = [full(t, y)[:2] for t, y in zip(times, states, strict=True)]
    zs, zds = np.array([m[0] for m in motion]), np.array([m[1] for m in motion])
    return ReferenceRun(
        t=times,
        head_xy=zs[:, 0:2],
        head_yaw=zs[:, 2],
        q=zs[:, 3:],
        crossed=crossed,
        wall_time_s=wall,
        z_dot=zds,
        circled=bool(fired) and not crossed,
        joint_torque=np.array([working_torque(t, y) for t, y in zip(times, states, strict=True)]),
    )
