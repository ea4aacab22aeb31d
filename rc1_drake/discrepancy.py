"""A discrepancy model: a generalized force linear in its coefficients, for an effect that no library lists
(universal differential equations' missing term, kept sparse and physical so that it can be named).

Terms act at sites on the body — the head's centre, each wheel (modules 2-14) and the tail's end — as forces in
the module's frame that are fixed shapes of the site's velocity u = (u_long, u_lat) (site_shapes), and in the
failed joints as torques that are fixed shapes of the joint's angle and rate (joint_shapes). A term's coefficient
is shared by the sites of its group (GROUPS). The step adds sum_k theta_k phi_k(x) inside the implicit friction
solve beside Eqs. 4-5 (friction.assemble_step: the velocity shapes at the step's end velocity; the joint bias and
spring at its start), the tangent model differentiates it exactly (engine/tangent.py), and effects/terms.py registers
each term as an effect of the `discrepancy` group, so that a model file, compare and a fit take it like any other.

Sign conventions are the README's: +long rolls toward the head, +lat is the module's left; a positive
coefficient of a drag or dry term resists the motion.

To add a term: a site kind is a column of site_shapes (and its rates in site_shape_rates), a joint kind a column
of joint_shapes; a group is a set of sites. tests/test_discrepancy.py checks the shapes against hand values and
their rates against central differences, whatever the columns.
"""

import numpy as np

from .kinematics import jit

# Sites: 0 the head's centre (the wheelless head, where a cable or a skid would act), 1-13 the wheels of modules
# 2-14, 14 the tail's end (its front joint mirrored through its centre, where RC1's power tether was attached).
NUM_SITES = 15
TAIL_END = NUM_SITES - 1
GROUPS = {  # name -> sites; each site in one group at most
    "head": (0,),
    "front": (1, 2, 3, 4),  # wheels of modules 2-5
    "middle": (5, 6, 7, 8, 9),  # modules 6-10
    "rear": (10, 11, 12, 13),  # modules 11-14
    "tail": (TAIL_END,),
}

# Site kinds: (name, unit, what it is in words). Force f = (f_long, f_lat) = site_shapes(u) @ theta.
SITE_KINDS = (
    ("drag_long", "N_s_per_m", "a viscous force against its longitudinal velocity"),
    ("drag_lat", "N_s_per_m", "a viscous force against its lateral velocity"),
    ("dry_long", "N", "a dry (Coulomb) force against its longitudinal velocity"),
    ("dry_lat", "N", "a dry (Coulomb) force against its lateral velocity"),
    ("side_by_long", "N_s_per_m", "a sideways force to its left proportional to its longitudinal velocity"),
    ("push_long", "N", "a constant force toward the head along its axis"),
    ("push_lat", "N", "a constant force to its left"),
    ("quad_long", "N_s2_per_m2", "a force against its longitudinal velocity, growing with its square (|v| v)"),
    ("quad_lat", "N_s2_per_m2", "a force against its lateral velocity, growing with its square (|v| v)"),
)
# Failed-joint kinds: torque tau = joint_shapes(q, q_dot) @ theta, in failed (free) joints only.
JOINT_KINDS = (
    ("bias", "Nm", "a constant torque"),
    ("spring", "Nm_per_rad", "a torque pulling it straight, proportional to its angle"),
    ("drag", "Nm_s_per_rad", "a viscous torque against its rate"),
    ("dry", "Nm", "a dry (Coulomb) torque against its rate"),
)
NSK, NJK = len(SITE_KINDS), len(JOINT_KINDS)
NUM_TERMS = len(GROUPS) * NSK + NJK
SITE_GROUP = np.full(NUM_SITES, -1, dtype=np.int64)
for _g, _sites in enumerate(GROUPS.values()):
    SITE_GROUP[list(_sites)] = _g


def term_names() -> list[tuple]:
    """Per coefficient, in the parameter vector's order: (group or 'failed_joint', kind, unit, words)."""
    out = [(group, *kind) for group in GROUPS for kind in SITE_KINDS]
    return out + [("failed_joint", *kind) for kind in JOINT_KINDS]


@jit
def site_shapes(u_long, u_lat, eps):
    """(2, NSK): the force (long, lat) of each site kind at unit coefficient; eps smooths the dry terms' sign."""
    out = np.zeros((2, NSK))
    out[0, 0] = -u_long
    out[1, 1] = -u_lat
    out[0, 2] = -u_long / np.sqrt(u_long * u_long + eps * eps)
    out[1, 3] = -u_lat / np.sqrt(u_lat * u_lat + eps * eps)
    out[1, 4] = u_long
    out[0, 5] = 1.0
    out[1, 6] = 1.0
    out[0, 7] = -abs(u_long) * u_long
    out[1, 8] = -abs(u_lat) * u_lat
    return out


@jit
def site_shape_rates(u_long, u_lat, eps):
    """(d site_shapes / d u_long, d site_shapes / d u_lat), each (2, NSK)."""
    along, across = np.zeros((2, NSK)), np.zeros((2, NSK))
    along[0, 0] = -1.0
    along[0, 2] = -(eps * eps) / (u_long * u_long + eps * eps) ** 1.5
    along[1, 4] = 1.0
    across[1, 1] = -1.0
    across[1, 3] = -(eps * eps) / (u_lat * u_lat + eps * eps) ** 1.5
    along[0, 7] = -2.0 * abs(u_long)
    across[1, 8] = -2.0 * abs(u_lat)
    return along, across


@jit
def joint_shapes(q, q_dot, eps):
    """(NJK,): a failed joint's torque of each kind at unit coefficient (bias, spring, drag, dry)."""
    return np.array([1.0, -q, -q_dot, -q_dot / np.sqrt(q_dot * q_dot + eps * eps)])


@jit
def site_force(u_long, u_lat, coefficients, eps):
    """A site's force (f_long, f_lat) and its rate d f / d (u_long, u_lat) (2, 2) for its group's coefficients."""
    along, across = site_shape_rates(u_long, u_lat, eps)
    shapes = site_shapes(u_long, u_lat, eps)
    force, rate = np.zeros(2), np.zeros((2, 2))
    for i in range(2):  # loops, not BLAS calls: a step makes ~90 of these
        for k in range(NSK):
            force[i] += shapes[i, k] * coefficients[k]
            rate[i, 0] += along[i, k] * coefficients[k]
            rate[i, 1] += across[i, k] * coefficients[k]
    return force, rate


@jit
def site_coefficients(theta):
    """(NUM_SITES, NSK): each site's coefficients from the term vector (zeros for a site in no group)."""
    out = np.zeros((NUM_SITES, NSK))
    for s in range(NUM_SITES):
        g = SITE_GROUP[s]
        if g >= 0:
            out[s] = theta[g * NSK : (g + 1) * NSK]
    return out


@jit
def site_arrays(chain):
    """(module, offset in the module's frame, unit 'toe') of the sites, as wheel_kinematics_kernel takes them:
    the head's centre, the wheels, the tail's end."""
    _, joint_in_child, wheel_module, wheel_offset, _ = chain
    nw = wheel_module.shape[0]
    module = np.zeros(nw + 2, dtype=np.int64)
    module[1 : nw + 1] = wheel_module
    module[nw + 1] = joint_in_child.shape[0]
    offset = np.zeros(nw + 2, dtype=np.complex128)
    offset[1 : nw + 1] = wheel_offset
    offset[nw + 1] = -joint_in_child[-1]
    return module, offset, np.ones(nw + 2, dtype=np.complex128)
