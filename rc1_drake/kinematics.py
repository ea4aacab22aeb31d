"""Planar kinematics of the RC1 chain: pure numpy kernels, compiled with numba for the time step.

Conventions (README, "Conventions"): world x toward the finish line, y to the left, z up. The base
coordinates are the head module's centre (x, y) and yaw; q_i (i = 1..13) is the yaw of module i+1
relative to module i, counter-clockwise positive. Module k's frame has its origin at the module centre
and +x pointing toward the head. Arrays here are 0-based: module 0 is the head, joint j joins module j
(parent) to module j+1 (child). The plant state is x = [x, y, yaw, q_1..q_13; vx, vy, w, q_dot].

Planar vectors are complex numbers x + iy: rotating by yaw is multiplying by exp(i yaw) and z x v is
i v. The geometry (joint and wheel locations) is read from the plant, so `models/rc1.sdf` stays the
single source of truth; see `model.chain_geometry`.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
from pathlib import Path

import numba
import numpy as np


def _drop_stale_kernel_caches() -> None:
    """numba keys a cached kernel on its own file only, so a kernel whose callee (in another file) changed
    would load stale code: the package's caches are dropped whenever any of its sources changes."""
    package = Path(__file__).resolve().parent
    sources = sorted(package.rglob("*.py"))
    stamp = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()
    for cache in {p.parent / "__pycache__" for p in sources}:
        marker = cache / "rc1_kernels.stamp"
        try:
            if marker.read_text() == stamp:
                continue
        except OSError:
            pass
        try:
            cache.mkdir(exist_ok=True)
            for old in (*cache.glob("*.nbi"), *cache.glob("*.nbc")):
                old.unlink(missing_ok=True)
            temporary = cache / f"rc1_kernels.stamp.{os.getpid()}"
            temporary.write_text(stamp)
            temporary.replace(marker)
        except OSError:  # a read-only install: numba then compiles in memory
            pass


_drop_stale_kernel_caches()
jit = functools.partial(numba.njit, cache=True)


@dataclasses.dataclass(frozen=True)
class ChainGeometry:
    """Where the joints and wheels sit on the modules (module frames; metres, radians, kg)."""

    joint_in_parent: np.ndarray  # (13,) complex: joint j in module j's frame
    joint_in_child: np.ndarray  # (13,) complex: joint j in module j+1's frame
    wheel_module: np.ndarray  # (W,) int: 0-based module carrying each wheel
    wheel_offset: np.ndarray  # (W,) complex: wheel axle centre in its module's frame
    wheel_yaw: np.ndarray  # (W,) rolling direction relative to the module's +x (toe angle)
    module_mass: np.ndarray  # (14,)
    module_yaw_inertia: np.ndarray  # (14,) about the module centre

    @property
    def num_modules(self) -> int:
        return len(self.module_mass)

    @property
    def num_joints(self) -> int:
        return len(self.joint_in_parent)

    @functools.cached_property
    def arrays(self) -> tuple:
        """The arrays the compiled kernels take, in their argument order."""
        return (
            np.ascontiguousarray(self.joint_in_parent, dtype=np.complex128),
            np.ascontiguousarray(self.joint_in_child, dtype=np.complex128),
            np.ascontiguousarray(self.wheel_module, dtype=np.int64),
            np.ascontiguousarray(self.wheel_offset, dtype=np.complex128),
            np.exp(1j * np.asarray(self.wheel_yaw, dtype=float)),
        )


def module_yaws(head_yaw, q):
    """Absolute module yaws phi_k = head_yaw + q_1 + ... + q_{k-1}, for q of shape (..., 13)."""
    q = np.asarray(q, dtype=float)
    zero = np.zeros(q.shape[:-1] + (1,))
    return np.asarray(head_yaw)[..., None] + np.concatenate([zero, np.cumsum(q, axis=-1)], axis=-1)


def module_positions(head_xy, phi, geometry: ChainGeometry):
    """Module centres (..., 14) complex from the head centre (complex) and module yaws (..., 14)."""
    e = np.exp(1j * phi)
    steps = e[..., :-1] * geometry.joint_in_parent - e[..., 1:] * geometry.joint_in_child
    zero = np.zeros(steps.shape[:-1] + (1,), dtype=complex)
    return np.asarray(head_xy)[..., None] + np.concatenate([zero, np.cumsum(steps, axis=-1)], axis=-1)


@jit
def _module_motion(x, joint_in_parent, joint_in_child):
    nj = joint_in_parent.shape[0]
    nq = 3 + nj
    phi = np.cumsum(x[2:nq])  # [yaw, q_1..q_13] -> module yaws
    phi_dot = np.cumsum(x[nq + 2 :])
    e = np.exp(1j * phi)
    p = np.empty(nj + 1, dtype=np.complex128)
    v = np.empty(nj + 1, dtype=np.complex128)
    p[0] = x[0] + 1j * x[1]
    v[0] = x[nq] + 1j * x[nq + 1]
    for j in range(nj):
        a = e[j] * joint_in_parent[j]
        b = e[j + 1] * joint_in_child[j]
        p[j + 1] = p[j] + a - b
        v[j + 1] = v[j] + 1j * (phi_dot[j] * a - phi_dot[j + 1] * b)
    return phi, phi_dot, p, v


def module_motion(x, geometry: ChainGeometry):
    """(phi, phi_dot, position, velocity) of the 14 module centres from the plant state.

    Positions and velocities are complex; they follow the chain p_{k+1} = p_k + R(phi_k) a_k -
    R(phi_{k+1}) b_k, with a, b the joint's location in the parent's and the child's frame.
    """
    jp, jc, *_ = geometry.arrays
    return _module_motion(np.asarray(x, dtype=float), jp, jc)


@jit
def chain_frames(x, joint_in_parent, joint_in_child):
    """(e (nm,): each module's heading e^{i phi_k}; p (nm,): its origin; joint (nj,): each joint's position), complex
    and in the world, from the plant state: the chain p_{k+1} = p_k + R(phi_k) a_k - R(phi_{k+1}) b_k walked once,
    for a step's wheel Jacobians and modules' inertias alike."""
    nj = joint_in_parent.shape[0]
    e = np.exp(1j * np.cumsum(x[2 : 3 + nj]))
    p = np.empty(nj + 1, dtype=np.complex128)
    joint = np.empty(nj, dtype=np.complex128)
    p[0] = x[0] + 1j * x[1]
    for j in range(nj):
        joint[j] = p[j] + e[j] * joint_in_parent[j]
        p[j + 1] = joint[j] - e[j + 1] * joint_in_child[j]
    return e, p, joint


@jit
def wheel_kinematics_at(frames, wheel_module, wheel_offset, wheel_toe):
    """wheel_kinematics from the chain's frames (chain_frames): positions, rolling directions, Jacobians."""
    e, p, joint_xy = frames
    nw = wheel_module.shape[0]
    position = np.empty(nw, dtype=np.complex128)
    direction = np.empty(nw, dtype=np.complex128)
    jacobian = np.zeros((nw, 3 + joint_xy.shape[0]), dtype=np.complex128)
    for w in range(nw):
        k = wheel_module[w]
        position[w] = p[k] + e[k] * wheel_offset[w]
        direction[w] = e[k] * wheel_toe[w]
        jacobian[w, 0] = 1.0
        jacobian[w, 1] = 1j
        jacobian[w, 2] = 1j * (position[w] - p[0])
        for j in range(k):  # joints 0..k-1 lie ahead of module k and turn it
            jacobian[w, 3 + j] = 1j * (position[w] - joint_xy[j])
    return position, direction, jacobian


@jit
def wheel_kinematics_kernel(x, joint_in_parent, joint_in_child, wheel_module, wheel_offset, wheel_toe):
    """wheel_kinematics on the geometry's arrays (compiled; the friction solve and the engine call it)."""
    return wheel_kinematics_at(chain_frames(x, joint_in_parent, joint_in_child), wheel_module, wheel_offset, wheel_toe)


@dataclasses.dataclass(frozen=True)
class WheelKinematics:
    position: np.ndarray  # (W,) complex, world
    direction: np.ndarray  # (W,) complex unit vector along the rolling direction, world
    jacobian: np.ndarray  # (W, 16) complex: wheel centre velocity (complex) = jacobian @ v


def wheel_kinematics(x, geometry: ChainGeometry) -> WheelKinematics:
    """Wheel positions, rolling directions and velocity Jacobians from the plant state.

    Turning a coordinate that rotates the bodies behind a point c moves a point p on them at
    i (p - c) per unit rate, so the Jacobian column of the head yaw is i (p_w - p_head) and that of
    joint j is i (p_w - c_j) for the wheels behind joint j (zero for those ahead of it).
    """
    return WheelKinematics(*wheel_kinematics_kernel(np.asarray(x, dtype=float), *geometry.arrays))
