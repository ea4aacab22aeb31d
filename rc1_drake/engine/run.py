"""A whole run of the RC1 Diagram as one compiled call: its sources, controllers, failure switch, step,
loggers and stop rules, with the Simulator's timing.

What each Diagram system does at step k (t_k = k dt):
- the joint command theta(t_k), theta_dot(t_k): the serpenoid (gait.py, Eqs. 3, 7) plus the gait bias
  plus, with heading control, clamp(kp e_k + ki z_k, +-limit), e_k = mean module yaw - reference; or
  a cubic Hermite reference (replays), its time clamped to the reference's span as PiecewisePolynomial's;
- the step (step.py) from x_k, which also gives the servo torque that the torque logger records at t_k,
  with the servo PID's (servo.py) command u_k = Ki z_k + Kp (theta - q_k) + Kd (theta_dot - q_dot_k);
- the plant's update first (Drake runs it as an unrestricted update, before the discrete ones), then the
  controllers' integrators from x_{k+1}: z+ = z + dt (theta - q_{k+1}), theta at t_k (its heading
  feedback also from x_{k+1});
- the failure switch between calls (session.py): a failure at t_f acts from the first update at t_k >= t_f;
- the loggers at t = j P record the state then; the monitor checks the state after each update
  (not finite: an error; x >= line: "crossed"; |yaw - yaw_0| >= 2 pi revolutions: "circling").
"""

from __future__ import annotations

import numpy as np

from ..friction import NEWTON_FINAL_STEP_M_S, TANGENT_FINAL_STEP_M_S
from ..kinematics import jit
from .step import plant_step, plant_terms
from .tangent import step_tangent

RUNNING, CROSSED, CIRCLING, NOT_FINITE = 0, 1, 2, 3
SERPENOID, REFERENCE = 0, 1


@jit
def _hermite(t, breaks, values, rates, segment):
    """Value and derivative of the C1 cubic through (breaks, values, rates) at t (clamped to the span);
    segment[0] caches the last segment found (runs advance in time)."""
    n = breaks.shape[0]
    t = min(max(t, breaks[0]), breaks[n - 1])
    i = min(segment[0], n - 2)
    while i > 0 and t < breaks[i]:
        i -= 1
    while i < n - 2 and t >= breaks[i + 1]:
        i += 1
    segment[0] = i
    h = breaks[i + 1] - breaks[i]
    s = (t - breaks[i]) / h
    s2, s3 = s * s, s * s * s
    c0, c1, c2, c3 = 2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h, -2 * s3 + 3 * s2, (s3 - s2) * h
    d0, d1, d2 = (6 * s2 - 6 * s), 3 * s2 - 4 * s + 1, 3 * s2 - 2 * s
    m = values.shape[1]
    value, rate = np.empty(m), np.empty(m)
    for k in range(m):  # a loop: the vector expression's temporaries were ~20 allocations, twice a step
        value[k] = c0 * values[i, k] + c1 * rates[i, k] + c2 * values[i + 1, k] + c3 * rates[i + 1, k]
        rate[k] = d0 * (values[i, k] - values[i + 1, k]) / h + d1 * rates[i, k] + d2 * rates[i + 1, k]
    return value, rate


@jit
def _command(t, x, source, gait, heading, z_heading, breaks, values, rates, segment):
    """theta, theta_dot (13,) at t and the heading controller's error (0 without one)."""
    error = 0.0
    if source == REFERENCE:
        theta, theta_dot = _hermite(t, breaks, values, rates, segment)
        return theta, theta_dot, error
    amp, omega, phase, bias = gait[0], gait[1], gait[2], gait[3]
    arg = omega * t - phase
    theta = amp * np.sin(arg) + bias
    theta_dot = amp * omega * np.cos(arg)
    if heading[0] != 0.0:  # active: [1, kp, ki, limit, reference, weights (16)]
        nq = heading.shape[0] - 5
        error = heading[5:] @ x[:nq] - heading[4]
        feedback = min(max(heading[2] * z_heading[0] + heading[1] * error, -heading[3]), heading[3])
        theta = theta + feedback
    return theta, theta_dot, error


@jit
def _servo_target(gains, theta, theta_dot, lower, upper):
    """What the servo's P and I terms aim at: theta, or for a kinematic joint (lead gains[3] > 0) the reference lead
    ahead within the joint's limits (servo._add_kinematic_target)."""
    if gains[3] > 0.0:
        return np.minimum(np.maximum(theta + gains[3] * theta_dot, lower), upper)
    return theta


@jit
def _servo_command(gains, z_pid, theta, theta_dot, x, lower, upper):
    """The servo PID's command Ki z + Kp (target - q) + Kd (theta_dot - q_dot) at state x (servo.add_servos)."""
    nq = x.shape[0] // 2
    target = _servo_target(gains, theta, theta_dot, lower, upper)
    command = np.empty(nq - 3)
    for k in range(nq - 3):  # a loop: no temporaries
        command[k] = gains[1] * z_pid[k] + gains[0] * (target[k] - x[3 + k]) + gains[2] * (theta_dot[k] - x[nq + 3 + k])
    return command


@jit
def _heading_gain(x, heading, z_heading):
    """d(feedback)/d(error) and d/d(z_heading) of the heading controller at x: kp and ki, or 0 where it saturates."""
    if heading[0] == 0.0:
        return 0.0, 0.0
    nq = heading.shape[0] - 5
    raw = heading[2] * z_heading[0] + heading[1] * (heading[5:] @ x[:nq] - heading[4])
    return (heading[1], heading[2]) if abs(raw) < heading[3] else (0.0, 0.0)


@jit
def _sensitivity_step(
    x,
    x_next,
    v_star,
    force_plus,
    command,
    sens,
    sens_z,
    sens_zh,
    dparams,
    dgravity,
    z_heading,
    dt,
    params,
    power,
    servo_gains,
    gains,
    heading,
    plant,
):
    """Carry the sensitivities through one step (tangent.step_tangent), the PID's command and integrators, and
    the heading controller (the serpenoid's and the replay reference's time terms do not depend on parameters)."""
    nq = x.shape[0] // 2
    num = sens.shape[0]
    weights = heading[5:]  # the heading's weights on the positions (zero without heading control)
    kp_h, ki_h = _heading_gain(x, heading, z_heading)
    dcommand = np.empty((num, nq - 3))
    for d in range(num):
        dtheta = kp_h * (weights @ sens[d, :nq]) + ki_h * sens_zh[d]
        dcommand[d] = gains[1] * sens_z[d] + gains[0] * (dtheta - sens[d, 3:nq]) - gains[2] * sens[d, nq + 3 :]
    new = step_tangent(
        x,
        force_plus,
        v_star,
        x_next[nq:],
        sens,
        dparams,
        dgravity,
        dcommand,
        dt,
        params,
        command,
        power,
        servo_gains,
        plant,
    )
    kp_n, ki_n = _heading_gain(x_next, heading, z_heading)
    for d in range(num):
        de = weights @ new[d, :nq]
        sens_z[d] += dt * (kp_n * de + ki_n * sens_zh[d] - new[d, 3:nq])
        sens_zh[d] += dt * de
    sens[:] = new


@jit
def advance_run(
    x,
    z_pid,
    z_heading,
    segment,
    k0,
    k1,
    t_first,
    dt,
    extra_force,
    params,
    power,
    locked,
    log_steps,
    log_times,
    log_next,
    last_torque,
    log_state,
    log_torque,
    source,
    gait,
    heading,
    breaks,
    values,
    rates,
    gains,
    stop,
    model,
    mass,
    yaw_inertia,
    com,
    lower,
    upper,
    chain,
    sens,
    sens_z,
    sens_zh,
    dparams,
    dgravity,
    log_sens,
):
    """Take the updates k0 <= k < k1 in place on the carried state (x, z_pid, z_heading, segment, log_next,
    last_torque); returns (status, k) with k the index of the state x now holds. Failures change params,
    power and locked between calls (session.py), as the failure switch does between AdvanceTo calls.

    gains: [kp, ki, kd, lead (s)];
    stop: [line x (nan: none), yaw turn (inf: none), yaw_0]; model: [gravity x, y, in plane (0/1)];
    t_first (nan: k0 dt) is the time of the first update (the Simulator's time at a stop between steps).
    Forward sensitivities (P directions, P may be 0): sens (P, 32), sens_z (P, 13) and sens_zh (P,) carry
    d(x, z_pid, z_heading) along the parameter directions dparams (P, len(params)) and dgravity (P, 2: gravity's
    floor components); log_sens (rows, P, 32).
    """
    nq = x.shape[0] // 2
    gravity_xy = model[0] + 1j * model[1]
    in_plane = model[2] != 0.0
    plant = plant_terms(mass, yaw_inertia, com, gravity_xy, in_plane, lower, upper, locked, chain)
    servo_gains = np.array([gains[0], gains[2]])
    final_step = TANGENT_FINAL_STEP_M_S if sens.shape[0] else NEWTON_FINAL_STEP_M_S
    for k in range(k0, k1):
        t = k * dt if k > k0 or np.isnan(t_first) else t_first
        theta, theta_dot, error = _command(t, x, source, gait, heading, z_heading, breaks, values, rates, segment)
        command = _servo_command(gains, z_pid, theta, theta_dot, x, lower, upper)
        x_next, torque, v_star, force_plus = plant_step(
            x,
            dt,
            params,
            command,
            power,
            servo_gains,
            extra_force,
            plant,
            final_step,
        )
        while log_next[0] < log_steps.shape[0] and log_steps[log_next[0]] == k:
            row = log_next[0]
            log_state[row] = x
            if sens.shape[0]:
                log_sens[row] = sens
            log_torque[row] = torque
            if log_times[row] != t:  # a log between two updates: the servo output at its own time
                theta, theta_dot, _ = _command(
                    log_times[row], x, source, gait, heading, z_heading, breaks, values, rates, segment
                )
                between = _servo_command(gains, z_pid, theta, theta_dot, x, lower, upper)
                log_torque[row] = plant_step(
                    x,
                    dt,
                    params,
                    between,
                    power,
                    servo_gains,
                    extra_force,
                    plant,
                    final_step,
                )[1]
            log_next[0] += 1
        last_torque[:] = torque
        # The plant updates its state before the controllers update theirs (an unrestricted update comes
        # first in Drake's Simulator), so the integrators see x_{k+1} and the command's time t_k.
        if sens.shape[0]:
            _sensitivity_step(
                x,
                x_next,
                v_star,
                force_plus,
                command,
                sens,
                sens_z,
                sens_zh,
                dparams,
                dgravity,
                z_heading,
                dt,
                params,
                power,
                servo_gains,
                gains,
                heading,
                plant,
            )
        theta, theta_dot, error = _command(t, x_next, source, gait, heading, z_heading, breaks, values, rates, segment)
        target = _servo_target(gains, theta, theta_dot, lower, upper)
        for j in range(nq - 3):
            z_pid[j] += dt * (target[j] - x_next[3 + j])
        z_heading[0] += dt * error
        x[:] = x_next
        if not np.isfinite(x[0]):
            return NOT_FINITE, k + 1
        if x[0] >= stop[0]:
            return CROSSED, k + 1
        if abs(x[2] - stop[2]) >= stop[1]:
            return CIRCLING, k + 1
    return RUNNING, k1
