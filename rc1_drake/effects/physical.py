"""The physical effects: the floor (its slope), the wheels (friction-law shapes, a toe), the head and the tail (a
skid, a cantilever, a tether), the failed joints (dry friction, a compliant stop), the masses (a payload) and the
servos (a lag)."""

import dataclasses
import math

import numpy as np

from ..config import GRAVITY_M_S2, JOINT_LIMIT_DEG, NUM_JOINTS, JointGait, Rc1Error, Servo
from .base import Effect, EffectParameter


class GroundSlope(Effect):
    name = "ground_slope"
    summary = "a tilted floor: gravity pulls every module downhill, the normal forces fall by cos(slope)"
    parameters = (
        EffectParameter("ground_slope_deg", 0.0, 20.0, probe=3.0),
        EffectParameter("ground_slope_direction_deg", -180.0, 180.0),
    )  # downhill, counter-clockwise from +x

    # A diagnosis fits the tilt as a vector (downhill x and y components, degrees): at slope 0 the
    # direction has no effect at all, and the residuals are smooth in the components. It searches only
    # floors a lab could have unnoticed (a 5 deg floor is a 1:11 ramp, steeper than a wheelchair ramp;
    # a spirit level sees 0.1 deg): free to 20 deg, a tilt absorbed what a lateral friction asymmetry does
    # to a turning gait (docs/diagnosis.md). A known ramp goes into the model file; the search then spans it.
    search_deg = 5.0

    def coordinates(self, values):
        slope, heading = values["ground_slope_deg"], math.radians(values["ground_slope_direction_deg"])
        return {"ground_slope_x_deg": slope * math.cos(heading), "ground_slope_y_deg": slope * math.sin(heading)}

    def coordinate_space(self):
        return [
            EffectParameter(f"ground_slope_{axis}_deg", -self.search_deg, self.search_deg, probe=3.0) for axis in "xy"
        ]

    def from_coordinates(self, coordinates):
        x, y = coordinates["ground_slope_x_deg"], coordinates["ground_slope_y_deg"]
        return {
            "ground_slope_deg": min(math.hypot(x, y), self.main.upper),
            "ground_slope_direction_deg": math.degrees(math.atan2(y, x)),
        }

    def configure(self, setup, values):
        slope, heading = math.radians(values["ground_slope_deg"]), math.radians(values["ground_slope_direction_deg"])
        setup.gravity = GRAVITY_M_S2 * np.array(
            [math.sin(slope) * math.cos(heading), math.sin(slope) * math.sin(heading), -math.cos(slope)]
        )


class LateralFrictionAsymmetry(Effect):
    name = "lateral_friction_asymmetry"
    summary = "the lateral Coulomb coefficient is mu_lat (1 + a) sliding left, mu_lat (1 - a) sliding right"
    parameters = (EffectParameter("lateral_friction_asymmetry", -0.9, 0.9, probe=0.2),)

    def configure(self, setup, values):
        setup.lateral_asymmetry = values["lateral_friction_asymmetry"]


class LongitudinalFrictionAsymmetry(Effect):
    name = "longitudinal_friction_asymmetry"
    summary = "rolling resistance mu_long (1 + a) rolling forward, mu_long (1 - a) rolling backward"
    parameters = (EffectParameter("longitudinal_friction_asymmetry", -0.9, 0.9, probe=0.2),)

    def configure(self, setup, values):
        setup.longitudinal_asymmetry = values["longitudinal_friction_asymmetry"]


class HeadDrag(Effect):
    name = "head_drag"
    summary = "the wheelless head slides on the floor: isotropic Coulomb friction mu m g at its centre"
    parameters = (EffectParameter("head_drag_mu", 0.0, 2.0, probe=0.2),)

    def configure(self, setup, values):
        setup.head_mu = values["head_drag_mu"]


class JointCoulombFriction(Effect):
    name = "joint_coulomb_friction"
    summary = "dry friction torque in a failed (free) joint, beside its viscous c_joint"
    failed_joints_only = True
    parameters = (EffectParameter("joint_coulomb_Nm", 0.0, 1.0, probe=0.05),)

    def configure(self, setup, values):
        setup.joint_coulomb_Nm = values["joint_coulomb_Nm"]


class CompliantStop(Effect):
    """The paper's joint-limit PD (section 3) in a failed joint, in place of the plant's stiff +-38 deg limit:
    past the onset angle (the limit, less a margin), a restoring torque -k (|q| - onset) sgn(q) - d q_dot
    (friction.compliant_stop), k = 1 / compliance. A back-driven servo's stop yields: the joint swings past 38 deg
    as far as the load compresses it, to a stiff backstop where the modules meet (model.STOP_BACKSTOP_DEG). Fitted as
    compliance, so that 0 is the paper's stiff limit and the model is continuous there (nested models)."""

    name = "compliant_stop"
    summary = "a failed joint meets a PD stop (compliance, damping) at +-38 deg in place of the stiff limit"
    failed_joints_only = True
    default_candidate = False
    differentiable = False  # its own columns by differences (k = 1 / compliance); the tangent has its torque's
    parameters = (
        EffectParameter("stop_compliance_rad_per_Nm", 0.0, 0.2, probe=0.01),
        EffectParameter("stop_d_Nm_s_per_rad", 0.0, 2.0, default=0.05),
        EffectParameter("stop_margin_deg", 0.0, 20.0, fitted=False, default=0.0),
    )

    def configure(self, setup, values):
        compliance = values["stop_compliance_rad_per_Nm"]
        setup.stop_k = 1.0 / compliance if compliance > 0.0 else 0.0
        setup.stop_d = values["stop_d_Nm_s_per_rad"]
        setup.stop_onset_rad = math.radians(JOINT_LIMIT_DEG - values["stop_margin_deg"])


def stop_backstops(effects: dict, failures) -> tuple:
    """The joints (1-based) whose stiff +-38 deg limit a compliant stop replaces by the backstop: the free failed
    joints, when `effects` give the stop a compliance (their limits: model.with_backstops). Fixed for a run (a Drake
    plant's limits are fixed when it is built), so a joint that fails later has its backstop from the start; its
    servo holds it within 38 deg."""
    if not effects.get("stop_compliance_rad_per_Nm", 0.0) > 0.0:
        return ()
    return tuple(sorted({f.joint for f in failures if f.mode == "free"}))


class HeadCantilever(Effect):
    """The wheelless head held off the floor by the four-bar linkage, rigid in pitch: module 2's wheel carries
    its weight, up to twice it when the head's centre is as far ahead of wheel 2 as wheel 3 is behind (the
    moment then lifts wheel 3 by the excess). 0 is the paper's model (the head's weight nowhere)."""

    name = "head_cantilever"
    summary = "module 2's wheel carries s head weights (up to 2: the head's moment), wheel 3 loses the excess over 1"
    default_candidate = False
    parameters = (EffectParameter("head_on_wheel2", 0.0, 2.0, probe=0.2),)

    def configure(self, setup, values):
        setup.head_on_wheel2 = values["head_on_wheel2"]


class TailTether(Effect):
    """RC1 was powered through one tether at its tail (paper section 2): the cable lying on the floor behind it
    drags the tail's end with its sliding friction (its weight on the floor times its friction coefficient),
    against the end's motion: an isotropic Coulomb force of T newtons there, in the implicit friction solve (both
    engines; friction.tail_end_jacobian). Outside the paper's model and the default candidates."""

    name = "tail_tether"
    summary = "a cable dragged behind the tail: a Coulomb force T against its end's motion"
    default_candidate = False
    differentiable = False  # the tangent model (engine/tangent.py) does not carry it
    parameters = (EffectParameter("tail_tether_N", 0.0, 2.0, probe=0.2),)

    def configure(self, setup, values):
        setup.tail_tether_N = values["tail_tether_N"]


class StribeckFriction(Effect):
    name = "stribeck_friction"
    summary = "lateral breakaway friction: mu_lat (1 + r exp(-(v/v_s)^2)) at low slip speed"
    parameters = (
        EffectParameter("stribeck_ratio", 0.0, 3.0, probe=0.5),
        EffectParameter("stribeck_speed_m_s", 1e-3, 0.2, fitted=False, default=0.01),
    )

    def configure(self, setup, values):
        setup.stribeck_ratio, setup.stribeck_speed_m_s = values["stribeck_ratio"], values["stribeck_speed_m_s"]


class WheelToe(Effect):
    name = "wheel_toe"
    summary = "every wheel's rolling direction yawed counter-clockwise from its module's axis"
    parameters = (EffectParameter("wheel_toe_deg", -10.0, 10.0, probe=1.0),)

    def configure(self, setup, values):
        setup.wheel_toe_rad = math.radians(values["wheel_toe_deg"])


class ModulePayload(Effect):
    name = "module_payload"
    summary = "an extra mass at one module's centre: its inertia, and its wheel's normal force"
    parameters = (
        EffectParameter("payload_kg", 0.0, 2.0, probe=0.3),
        EffectParameter("payload_module", 1, 14, fitted=False, default=7),
    )
    differentiable = False

    def configure(self, setup, values):
        module = values["payload_module"]
        if module != int(module):
            raise Rc1Error(f"effects.payload_module: must be a module number 1..14, got {module}")
        setup.payload_module, setup.payload_kg = int(module), values["payload_kg"]


class ServoLag(Effect):
    name = "servo_lag"
    summary = "a first-order servo response of time constant tau to the gait command"
    parameters = (EffectParameter("servo_lag_s", 0.0, 0.5, probe=0.05),)
    seen_in_replay = False  # replays drive the joints by their measured angles
    differentiable = False

    def gait(self, gait, values):
        """A first-order lag 1/(1 + tau s) of the serpenoid command A sin(omega t - phi) + B is, once its
        transient (a few tau) has passed, (A / sqrt(1 + (omega tau)^2)) sin(omega t - phi - atan(omega tau)) + B:
        the lagged command is again a serpenoid (Eqs. 3, 7), per joint."""
        from ..gait import serpenoid_parameters

        tau = values["servo_lag_s"]
        if tau == 0.0:
            return gait
        amp, omega, phase, bias = serpenoid_parameters(gait)
        gain, delay = 1.0 / np.sqrt(1.0 + (omega * tau) ** 2), np.arctan(omega * tau)
        joints = [
            JointGait(
                joint=j + 1,
                amplitude_deg=math.degrees(amp[j] * gain[j]),
                frequency_deg_s=math.degrees(omega[j]),
                phase_deg=math.degrees(phase[j] + delay[j]),
                bias_deg=math.degrees(bias[j]),
            )
            for j in range(NUM_JOINTS)
        ]
        return dataclasses.replace(gait, joints=joints)


class ServoLinkage(Effect):
    """Each servo drives its module through a compliant four-bar linkage, and its potentiometer reads the servo's
    shaft, not the joint: the shaft leads the joint by c tau (tau the torque the servo gives, c the compliance).
    A replay's working joint then follows its reading through a torsional spring 1 / c in place of the paper's
    kinematic joint (section 3), with the linkage's own damping d; a servo of gains (kp, ki, kd) acting on its
    shaft gives the joint kp (theta - q) / (1 + kp c) and its I and D terms scaled alike (the linkage
    quasi-static: its own resonance lies far above the gait's). 0 is the paper's rigid joint (nested models)."""

    name = "servo_linkage"
    summary = "a compliant linkage between each servo's shaft (what its potentiometer reads) and its joint"
    default_candidate = False
    differentiable = False  # its own columns by differences (k = 1 / compliance); the tangent follows the gains
    parameters = (
        EffectParameter("linkage_compliance_rad_per_Nm", 0.0, 0.2, probe=0.005),
        EffectParameter("linkage_damping_Nm_s_per_rad", 0.0, 1.0, fitted=False, default=0.05),
    )

    def servo(self, servo, values) -> Servo:
        compliance = values["linkage_compliance_rad_per_Nm"]
        if compliance == 0.0:
            return servo
        scale = 1.0 / (1.0 + servo.kp_Nm_per_rad * compliance)
        return dataclasses.replace(
            servo,
            kp_Nm_per_rad=servo.kp_Nm_per_rad * scale,
            ki_Nm_per_rad_s=servo.ki_Nm_per_rad_s * scale,
            kd_Nm_s_per_rad=servo.kd_Nm_s_per_rad * scale + values["linkage_damping_Nm_s_per_rad"],
        )

    def configure_sensors(self, sensors, values):
        sensors.linkage_rad_per_Nm = values["linkage_compliance_rad_per_Nm"]
