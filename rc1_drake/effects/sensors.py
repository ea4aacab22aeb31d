"""The sensor faults (Effect.sensor): the robot is the paper's, what its sensors report is not (SensorModel)."""

import dataclasses
import math

from ..config import Gait, JointGait, Rc1Error
from .base import Effect, EffectParameter


class PotentiometerFault(Effect):
    """A sensor fault of one joint's potentiometer (subclasses: how it misreads). RC1 records the servos' own
    potentiometers (paper section 2), so the fault sits either in the servo's loop (the servo drives the faulty
    reading to the command, so the joint moves off its command and the data show the command) or only in the data
    acquisition (its calibration: the joint follows the command and the data misread it, past the joint limit at
    the wave's peaks). A replay reads the measured angles back either way. One effect per joint, so that a
    diagnosis names the joint."""

    sensor = True
    differentiable = False  # it moves the gait command and the replay's reference, not the model's parameters
    kind = ""  # the effect's name is potentiometer_<kind>_j<joint>
    search = 0.0  # a diagnosis searches +-this much: what a calibration could have missed

    def __init__(self, joint: int, main: EffectParameter, summary: str):
        self.joint = joint
        self.name = f"potentiometer_{self.kind}_j{joint}"
        self.summary = summary
        # 1: in the servo's loop (the robot moves off its command); 0: in the acquisition only
        self.parameters = (main, EffectParameter(f"{self.name}_in_servo_loop", 0.0, 1.0, fitted=False, default=1.0))

    def coordinate_space(self):
        return [dataclasses.replace(self.main, lower=-self.search, upper=self.search)]

    def _in_loop(self, values) -> bool:
        key = self.parameters[1].key
        if values[key] not in (0.0, 1.0):
            raise Rc1Error(
                f"effects.{key}: must be 1 (the servo's loop) or 0 (the acquisition only), got {values[key]}"
            )
        return values[key] == 1.0

    def _with_joint(self, gait: Gait, **fields) -> Gait:
        """`gait` with this joint's own serpenoid terms replaced by `fields` (config.JointGait's)."""
        own = next((jg for jg in gait.joints if jg.joint == self.joint), JointGait(joint=self.joint))
        others = [jg for jg in gait.joints if jg.joint != self.joint]
        return dataclasses.replace(gait, joints=[*others, dataclasses.replace(own, **fields)])


class PotentiometerOffset(PotentiometerFault):
    """The potentiometer reads the angle plus a constant offset. In the servo's loop the joint settles at the
    command minus the offset (Eq. 7's bias B_i moved by -offset); a replay follows the readings minus the offset."""

    kind = "offset"
    search = 5.0  # deg

    def __init__(self, joint: int):
        super().__init__(
            joint,
            EffectParameter(f"potentiometer_offset_j{joint}_deg", -10.0, 10.0, probe=1.0),
            f"joint {joint}'s potentiometer reads the angle plus a constant offset (sensor fault)",
        )

    def configure_sensors(self, sensors, values):
        self._in_loop(values)
        sensors.angle_offsets_rad[self.joint - 1] += math.radians(values[self.main.key])

    def gait(self, gait, values):
        from ..gait import serpenoid_parameters

        offset = values[self.main.key]
        if offset == 0.0 or not self._in_loop(values):
            return gait
        return self._with_joint(gait, bias_deg=math.degrees(serpenoid_parameters(gait)[3][self.joint - 1]) - offset)


class PotentiometerGain(PotentiometerFault):
    """The potentiometer reads the angle times (1 + a gain error), a calibration's slope missed as
    PotentiometerOffset's intercept can be. In the servo's loop the joint's amplitude and bias (Eq. 7) shrink by
    1 + error; a replay follows the readings divided by 1 + error."""

    kind = "gain"
    search = 0.1  # 10%

    def __init__(self, joint: int):
        super().__init__(
            joint,
            EffectParameter(f"potentiometer_gain_j{joint}_error", -0.5, 0.5, probe=0.02),
            f"joint {joint}'s potentiometer reads the angle times (1 + a gain error) (sensor fault)",
        )

    def configure_sensors(self, sensors, values):
        self._in_loop(values)
        sensors.angle_gains[self.joint - 1] *= 1.0 + values[self.main.key]

    def gait(self, gait, values):
        from ..gait import serpenoid_parameters

        error = values[self.main.key]
        if error == 0.0 or not self._in_loop(values):
            return gait
        amplitude, _, _, bias = (math.degrees(v[self.joint - 1]) for v in serpenoid_parameters(gait))
        return self._with_joint(gait, amplitude_deg=amplitude / (1.0 + error), bias_deg=bias / (1.0 + error))


class CameraDelay(Effect):
    name = "camera_delay"
    summary = "the overhead camera's clock runs behind the robot's: a frame stamped t shows the head at t - delay"
    parameters = (EffectParameter("camera_delay_s", -0.5, 0.5, probe=0.05),)
    sensor = True
    differentiable = False  # it moves what the camera is predicted to see, not the run

    def configure_sensors(self, sensors, values):
        sensors.camera_delay_s += values["camera_delay_s"]


class ImuFault(Effect):
    name = "imu_fault"
    summary = "the head IMU reports (1 + scale error) x yaw rate + a bias common to every trial"
    parameters = (
        EffectParameter("imu_scale_error", -0.5, 0.5, probe=0.05),
        EffectParameter("imu_bias_rad_s", -0.5, 0.5, probe=0.02),
    )
    sensor = True
    differentiable = False

    def configure_sensors(self, sensors, values):
        sensors.imu_scale *= 1.0 + values["imu_scale_error"]
        sensors.imu_bias_rad_s += values["imu_bias_rad_s"]
