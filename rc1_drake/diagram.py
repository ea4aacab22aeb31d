"""The RC1 Diagram: plant, serpenoid source, PID servos, failure switch, wheel friction, IMU, loggers.

    serpenoid + gait_bias -> servo_pid (command) + servo_power -> friction -> rc1_plant.actuation (servo torque)
    rc1_plant.state -> friction -> rc1_plant.applied_generalized_force (friction)
    rc1_plant.state -> head_imu (head yaw rate); loggers record the state and the servo torques.

The failure switch (servo.FailureSwitch) acts on a context: it sets a failed joint's servo power to
zero and turns its joint friction on, at t = 0 or, for a later failure, between two time steps.

What the Diagram fixes at build time (gait amplitudes, frequencies and phases, servo gains, time
step, log period, the joints whose stiff limit a compliant stop replaces) is `build_key(scenario)`;
everything else (friction coefficients, failures, bias, start pose) is set per run in the context by
`configure_context`, so batch work reuses one Diagram.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    AffineSystem,
    LinearSystem,
    LogVectorOutput,
    MatrixGain,
    Saturation,
    TrajectorySource,
)

from .config import Scenario
from .effects import commanded_gait, running_servo, stop_backstops
from .friction import FrictionForces
from .gait import add_gait_source, serpenoid_parameters
from .model import RC1Plant, add_rc1_plant
from .servo import FailureSwitch, add_servos


@dataclasses.dataclass
class RC1Diagram:
    diagram: object
    rc1: RC1Plant
    friction: FrictionForces
    failure_switch: FailureSwitch
    gait_bias: object  # ConstantVectorSource, or None when the servos follow a joint reference
    state_logger: object
    torque_logger: object
    build_key: tuple

    @property
    def plant(self):
        return self.rc1.plant


def build_key(scenario: Scenario, joint_reference=None) -> tuple:
    """The scenario fields a built Diagram depends on; equal keys can share a Diagram."""
    if joint_reference is None:
        amp, omega, phase, _ = serpenoid_parameters(commanded_gait(scenario.gait, scenario.effects))
        source = (tuple(amp), tuple(omega), tuple(phase))
    else:
        source = ("joint_reference", id(joint_reference))
    s, n = running_servo(scenario.servo, scenario.effects), scenario.numerics
    return source + (
        s.kp_Nm_per_rad,
        s.ki_Nm_per_rad_s,
        s.kd_Nm_s_per_rad,
        s.lead_s,
        n.time_step_s,
        n.log_period_s,
        dataclasses.astuple(scenario.heading_control),
        stop_backstops(scenario.effects, scenario.failures),
    )


def add_heading_control(builder, plant, scenario: Scenario):
    """A discrete PI controller from the body's heading (mean module yaw) to a common bias; returns
    its output port (see config.HeadingControl)."""
    hc = scenario.heading_control
    nq = plant.num_positions()
    n_joints = nq - 3
    # Mean module yaw = head yaw + (1/14) sum_k (q_1 + ... + q_{k-1}) = head yaw + sum_i (14 - i)/14 q_i.
    heading = np.zeros((1, 2 * nq))
    heading[0, 2] = 1.0
    heading[0, 3:nq] = (n_joints + 1 - np.arange(1, n_joints + 1)) / (n_joints + 1)
    dt = scenario.numerics.time_step_s
    # Input psi; state z = sum (psi - psi_ref) dt; bias = -kp (psi_ref - psi) - ki (-z) = kp (psi - psi_ref) + ki z.
    ref = math.radians(hc.heading_ref_deg)
    sense = builder.AddSystem(
        AffineSystem(
            A=np.zeros((0, 0)), B=np.zeros((0, 2 * nq)), f0=np.zeros(0), C=np.zeros((1, 0)), D=heading, y0=[-ref]
        )
    )
    sense.set_name("heading_error")
    pi = builder.AddSystem(LinearSystem(A=[[1.0]], B=[[dt]], C=[[hc.ki_per_s]], D=[[hc.kp]], time_period=dt))
    pi.set_name("heading_controller")
    limit = math.radians(hc.bias_limit_deg)
    clamp = builder.AddSystem(Saturation([-limit], [limit]))
    clamp.set_name("feedback_bias_limit")
    builder.Connect(plant.get_state_output_port(), sense.get_input_port())
    builder.Connect(sense.get_output_port(), pi.get_input_port())
    builder.Connect(pi.get_output_port(), clamp.get_input_port())
    return clamp.get_output_port()


def add_friction(builder, rc1, servo_power, servo_command_port, scenario: Scenario) -> FrictionForces:
    """Add the wheel and joint friction (Eqs. 4-5, c_joint; friction.FrictionForces), solved implicitly with
    the servos' torque, between the plant's state, the servos' command and power, and the plant's applied
    generalized force and actuation."""
    plant = rc1.plant
    servo = running_servo(scenario.servo, scenario.effects)
    friction = builder.AddSystem(
        FrictionForces(
            plant,
            rc1.geometry,
            scenario.friction,
            scenario.numerics.sgn_smoothing_m_s,
            servo_gains=(servo.kp_Nm_per_rad, servo.kd_Nm_s_per_rad),
        )
    )
    friction.set_name("friction")
    builder.Connect(plant.get_state_output_port(), friction.GetInputPort("plant_state"))
    builder.Connect(servo_command_port, friction.GetInputPort("servo_command"))
    builder.Connect(servo_power.get_output_port(), friction.GetInputPort("servo_power"))
    builder.Connect(friction.GetOutputPort("generalized_force"), plant.get_applied_generalized_force_input_port())
    builder.Connect(friction.GetOutputPort("servo_torque"), plant.get_actuation_input_port())
    return friction


def diagram_svg(diagram, *, max_depth: int = 1) -> str:
    """The Diagram drawn by Graphviz's dot (scripts/setup.sh installs it), as SVG text."""
    import shutil
    import subprocess

    from .config import Rc1Error

    if shutil.which("dot") is None:
        raise Rc1Error("drawing a Diagram needs Graphviz's dot program: run scripts/setup.sh (it installs graphviz)")
    dot = diagram.GetGraphvizString(max_depth=max_depth)
    return subprocess.run(["dot", "-Tsvg"], input=dot, capture_output=True, text=True, check=True).stdout


def build_diagram(scenario: Scenario, *, joint_reference=None) -> RC1Diagram:
    """The Diagram for `scenario`; with `joint_reference` (a Drake trajectory of the 13 joint angles,
    e.g. measured ones) the servos follow it instead of the serpenoid."""
    builder = DiagramBuilder()
    rc1 = add_rc1_plant(
        builder,
        time_step=scenario.numerics.time_step_s,
        backstops=stop_backstops(scenario.effects, scenario.failures),
    )
    plant = rc1.plant
    if joint_reference is None:
        feedback = add_heading_control(builder, plant, scenario) if scenario.heading_control.active else None
        desired_state, bias = add_gait_source(
            builder, commanded_gait(scenario.gait, scenario.effects), bias_input=feedback
        )
    else:
        source = builder.AddSystem(TrajectorySource(joint_reference, output_derivative_order=1))
        source.set_name("joint_reference")
        desired_state, bias = source.get_output_port(), None
    power, servo_command = add_servos(
        builder, rc1, desired_state, running_servo(scenario.servo, scenario.effects), scenario.numerics.time_step_s
    )
    friction = add_friction(builder, rc1, power, servo_command, scenario)
    servo_torque = friction.GetOutputPort("servo_torque")

    nq = plant.num_positions()
    imu_select = np.zeros((1, 2 * nq))
    imu_select[0, nq + 2] = 1.0  # the base yaw rate is the head module's yaw rate
    imu = builder.AddSystem(MatrixGain(imu_select))
    imu.set_name("head_imu")
    builder.Connect(plant.get_state_output_port(), imu.get_input_port())

    builder.ExportOutput(plant.get_state_output_port(), "plant_state")
    builder.ExportOutput(imu.get_output_port(), "head_yaw_rate")
    builder.ExportOutput(servo_torque, "servo_torque")

    period = scenario.numerics.log_period_s
    state_logger = LogVectorOutput(plant.get_state_output_port(), builder, period)
    state_logger.set_name("state_logger")
    torque_logger = LogVectorOutput(servo_torque, builder, period)
    torque_logger.set_name("torque_logger")

    diagram = builder.Build()
    diagram.set_name("rc1")
    return RC1Diagram(
        diagram=diagram,
        rc1=rc1,
        friction=friction,
        failure_switch=FailureSwitch(rc1, power, friction),
        gait_bias=bias,
        state_logger=state_logger,
        torque_logger=torque_logger,
        build_key=build_key(scenario, joint_reference),
    )
