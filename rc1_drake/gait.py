"""Serpenoid gait, paper Eqs. 3 and 7: theta_i(t) = A_i sin(omega_i t - phi_i) + B_i."""

from __future__ import annotations

import numpy as np
from pydrake.systems.primitives import Adder, ConstantVectorSource, MatrixGain, Multiplexer, Sine

from .config import NUM_JOINTS, Gait


def serpenoid_parameters(gait: Gait):
    """Per-joint (A, omega, phi, B) for joints 1..13 in rad and rad/s.

    phi_i = (i - 1) * phase_step - phase_offset unless a joint override sets phi_i itself.
    """
    i = np.arange(NUM_JOINTS)
    amp = np.full(NUM_JOINTS, gait.amplitude_deg)
    freq = np.full(NUM_JOINTS, gait.frequency_deg_s)
    phase = i * gait.phase_step_deg - gait.phase_offset_deg
    bias = np.full(NUM_JOINTS, gait.bias_deg)
    for jg in gait.joints:
        j = jg.joint - 1
        for arr, value in (
            (amp, jg.amplitude_deg),
            (freq, jg.frequency_deg_s),
            (phase, jg.phase_deg),
            (bias, jg.bias_deg),
        ):
            if value is not None:
                arr[j] = value
    return np.radians(amp), np.radians(freq), np.radians(phase), np.radians(bias)


def serpenoid(t, gait: Gait):
    """Joint angles and rates (13,) at time t (Eqs. 3, 7)."""
    amp, omega, phase, bias = serpenoid_parameters(gait)
    arg = omega * t - phase
    return amp * np.sin(arg) + bias, amp * omega * np.cos(arg)


def add_gait_source(builder, gait: Gait, *, bias_input=None):
    """Add the serpenoid source; returns (desired_state output port [theta; theta_dot], bias source).

    Drake's Sine computes a sin(omega t + p), so p = -phi_i. The bias B_i is a separate constant
    source whose value lives in the context, so a run can change it without rebuilding. A
    `bias_input` port (a scalar, e.g. a heading controller's output) adds to every joint's bias.
    """
    amp, omega, phase, bias = serpenoid_parameters(gait)
    sine = builder.AddSystem(Sine(amp, omega, -phase))
    sine.set_name("serpenoid")
    bias_source = builder.AddSystem(ConstantVectorSource(bias))
    bias_source.set_name("gait_bias")
    adder = builder.AddSystem(Adder(2 if bias_input is None else 3, NUM_JOINTS))
    adder.set_name("gait_plus_bias")
    if bias_input is not None:
        spread = builder.AddSystem(MatrixGain(np.ones((NUM_JOINTS, 1))))
        spread.set_name("feedback_bias_to_joints")
        builder.Connect(bias_input, spread.get_input_port())
        builder.Connect(spread.get_output_port(), adder.get_input_port(2))
    mux = builder.AddSystem(Multiplexer([NUM_JOINTS, NUM_JOINTS]))
    mux.set_name("gait_desired_state")
    builder.Connect(sine.get_output_port(0), adder.get_input_port(0))
    builder.Connect(bias_source.get_output_port(), adder.get_input_port(1))
    builder.Connect(adder.get_output_port(), mux.get_input_port(0))
    builder.Connect(sine.get_output_port(1), mux.get_input_port(1))
    return mux.get_output_port(), bias_source
