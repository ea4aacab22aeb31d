"""Per-joint PID servos (HS5645MG, torque-limited) and the failure switch (paper section 3).

A working joint i gets u_i = clamp(Kp e_i + Ki sum(e_i) dt + Kd de_i/dt, -e_max_i, e_max_i) with
e_i = theta_i - q_i: a discrete PID sampled at the plant's step (the servo is a digital one). The
torque the plant receives takes the proportional and derivative parts at the step's end (backward
Euler, solved with the friction in friction.FrictionForces), so the servos are stable at any step.
e_max_i, the servo's power, is the value of the `servo_power` source (kept in the context):
1.19 N m (the SDF's effort limit) while the joint works. A replay's servo is the paper's kinematic joint
(config.Servo.lead_s > 0, replay.REPLAY_SERVO): e_i is taken to the reference lead_s ahead, within the limits.

The failure switch acts on the context at the failure time: the failed joint's servo power drops to
zero, so its PID no longer reaches the joint, and the joint's viscous friction c_joint (a parameter
of friction.FrictionForces) turns on. The plant's joint limits (+-38 deg, constraints of the
discrete SAP solver) supply the restoring torque at the limits that the paper's joint-limit PD
controller provides.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.primitives import ConstantVectorSource, LinearSystem, MatrixGain, Multiplexer, Saturation

from .config import NUM_JOINTS, Failure, Servo
from .friction import FAILED, FREE, LOCKED, WORKING


class FailureSwitch:
    """Applies failures to a context (paper Fig. 4): a `free` joint's servo power drops to 0 and its
    joint friction c_joint acts; a `locked` joint is also held by the plant at its current angle;
    a `weak` joint's servo keeps tracking with its power cut to weak_torque_Nm."""

    def __init__(self, rc1, power_system, friction_system):
        self._effort = rc1.effort_limit
        self._joints = rc1.joints
        self._power = power_system
        self._friction = friction_system

    def reset(self, root_context, torque_limit=None) -> None:
        """Every servo powered (to the SDF's effort limit, or `torque_limit`), no failed joint."""
        power = self._effort if torque_limit is None else np.full_like(self._effort, torque_limit)
        self._power_parameter(root_context).SetFromVector(power)
        self._states(root_context)[:] = WORKING
        plant_context = self._plant_context(root_context)
        for joint in self._joints:
            if joint.is_locked(plant_context):
                joint.Unlock(plant_context)

    def fail(self, root_context, failure: Failure) -> None:
        j = failure.joint - 1
        if failure.mode == "weak":
            self._power_parameter(root_context).SetAtIndex(j, min(failure.weak_torque_Nm, self._effort[j]))
            return
        self._power_parameter(root_context).SetAtIndex(j, 0.0)
        if failure.mode == "locked":
            self._joints[j].Lock(self._plant_context(root_context))
            self._states(root_context)[j] = LOCKED
        else:
            self._states(root_context)[j] = FREE

    def _plant_context(self, root_context):
        return self._joints[0].GetParentPlant().GetMyMutableContextFromRoot(root_context)

    def _power_parameter(self, root_context):
        return self._power.get_mutable_source_value(self._power.GetMyMutableContextFromRoot(root_context))

    def _states(self, root_context):
        return self._friction.parameters(self._friction.GetMyMutableContextFromRoot(root_context))[FAILED]


def _add_kinematic_target(builder, rc1, desired_state_port, lead_s: float):
    """The target of a kinematic joint (config.Servo.lead_s > 0): the reference lead_s ahead, theta + lead_s theta_dot,
    within the joint's limits (a reading past a limit is a sensor's, not a place the joint can be driven to)."""
    n = NUM_JOINTS
    preview = builder.AddSystem(MatrixGain(np.block([[np.eye(n), lead_s * np.eye(n)], [np.zeros((n, n)), np.eye(n)]])))
    preview.set_name("kinematic_preview")
    lower = [j.position_lower_limits()[0] for j in rc1.joints]
    upper = [j.position_upper_limits()[0] for j in rc1.joints]
    limits = builder.AddSystem(
        Saturation(np.concatenate([lower, np.full(n, -np.inf)]), np.concatenate([upper, np.full(n, np.inf)]))
    )
    limits.set_name("kinematic_target")
    builder.Connect(desired_state_port, preview.get_input_port())
    builder.Connect(preview.get_output_port(), limits.get_input_port())
    return limits.get_output_port()


def add_servos(builder, rc1, desired_state_port, servo: Servo, time_step: float):
    """Add the PID servos and their power (torque limit) source; returns (servo_power system, command port).

    The command u_n is the PID sampled at the step's start; friction.FrictionForces turns it into the
    torque the plant receives (its proportional and derivative parts at the step's end, clamped to the power).
    """
    plant = rc1.plant
    nq = plant.num_positions()
    n = NUM_JOINTS
    # Input u = [theta; theta_dot; plant state [x, y, yaw, q; vx, vy, w, q_dot]].
    error = np.zeros((n, 2 * n + 2 * nq))  # e = theta - q
    error[:, :n] = np.eye(n)
    error[:, 2 * n + 3 : 2 * n + nq] = -np.eye(n)
    rate_error = np.zeros_like(error)  # de/dt = theta_dot - q_dot
    rate_error[:, n : 2 * n] = np.eye(n)
    rate_error[:, 2 * n + nq + 3 :] = -np.eye(n)
    # State z = running sum of e dt: z+ = z + dt e;  u = Ki z + Kp e + Kd de/dt.
    pid = builder.AddSystem(
        LinearSystem(
            A=np.eye(n),
            B=time_step * error,
            C=servo.ki_Nm_per_rad_s * np.eye(n),
            D=servo.kp_Nm_per_rad * error + servo.kd_Nm_s_per_rad * rate_error,
            time_period=time_step,
        )
    )
    pid.set_name("servo_pid")
    inputs = builder.AddSystem(Multiplexer([2 * n, 2 * nq]))
    inputs.set_name("servo_inputs")
    # The servo power (each servo's torque limit) is a constant source: its value lives in the
    # context, so the failure switch changes it per run, and the default context is a working robot.
    power = builder.AddSystem(ConstantVectorSource(rc1.effort_limit))
    power.set_name("servo_power")
    if servo.lead_s > 0.0:
        desired_state_port = _add_kinematic_target(builder, rc1, desired_state_port, servo.lead_s)
    builder.Connect(desired_state_port, inputs.get_input_port(0))
    builder.Connect(plant.get_state_output_port(), inputs.get_input_port(1))
    builder.Connect(inputs.get_output_port(), pid.get_input_port())
    return power, pid.get_output_port()
