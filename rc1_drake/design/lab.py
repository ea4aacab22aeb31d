"""What a lab can run (issue 68): the floor, the failures it can induce, its sensors, and the trials RC1's servos
and joints allow. A `Lab` is a YAML file (read with Drake's yaml_load_typed); its default is what the paper's
experiment needed. A `TrialDesign` is one trial to run: the gait (Eqs. 3 and 7), the joints powered off at its
start, how long."""

import dataclasses
import math
from pathlib import Path

import numpy as np

from ..config import JOINT_LIMIT_DEG, NUM_JOINTS, Failure, Gait, Rc1Error, Scenario, Start, Stop
from ..synthesize import SERVO_SPEED_LIMIT_DEG_S, Case

MIN_TURNING_RADIUS_M = 0.6  # RC1's tightest turn (paper section 4)
# Twice the paper's gait frequency: a drawn gait at 382 deg/s (21 deg, within the servos' speed) made data no servo
# could (a joint jumping 9 deg in 10 ms), refused by the loader.
MAX_FREQUENCY_DEG_S = 280.0


@dataclasses.dataclass
class Lab:
    """The floor (a rectangle the head's path must stay on, in the frame where each trial starts at the origin
    heading +x), the failures the lab can induce (sets of joints powered off at the start), its sample period and
    potentiometer noise, and the trials' shortest and longest durations. The default is the paper's experiment:
    a 4 m lane to the 3.18 m line, failures of joints 2, 7 and 13, 100 Hz."""

    floor_x_m: list[float] = dataclasses.field(default_factory=lambda: [-0.5, 4.0])
    floor_y_m: list[float] = dataclasses.field(default_factory=lambda: [-1.5, 1.5])
    failures: list[list[int]] = dataclasses.field(default_factory=lambda: [[], [2], [7], [13]])
    sample_period_s: float = 0.01
    potentiometer_deg: float = 0.25
    min_seconds: float = 3.0
    max_seconds: float = 10.0

    def check(self, where: str = "lab") -> None:
        """Rc1Error naming the first field that cannot be."""
        for name in ("floor_x_m", "floor_y_m"):
            low, high = (list(getattr(self, name)) + [math.nan, math.nan])[:2]
            if len(getattr(self, name)) != 2 or not low < 0.0 < high:
                raise Rc1Error(f"{where}: {name} must be [low, high] about the start (0), got {getattr(self, name)}")
        for failed in self.failures:
            if any(not 1 <= j <= NUM_JOINTS for j in failed):
                raise Rc1Error(f"{where}: failures: joint numbers are 1..{NUM_JOINTS}, got {failed}")
        if not 0.0 < self.sample_period_s <= 0.1:
            raise Rc1Error(f"{where}: sample_period_s must be in (0, 0.1] s, got {self.sample_period_s}")
        if not 0.0 < self.min_seconds <= self.max_seconds:
            raise Rc1Error(f"{where}: need 0 < min_seconds <= max_seconds, got {self.min_seconds}, {self.max_seconds}")


def load_lab(path) -> Lab:
    """A Lab from a YAML file, checked (Rc1Error naming the file and what is wrong)."""
    from pydrake.common.yaml import yaml_load_typed

    path = Path(path)
    if not path.is_file():
        raise Rc1Error(f"{path}: no such lab file")
    try:
        lab = yaml_load_typed(schema=Lab, filename=str(path))
    except RuntimeError as error:
        raise Rc1Error(f"{path}: {str(error).splitlines()[0]}") from None
    lab.check(str(path))
    return lab


@dataclasses.dataclass(frozen=True)
class TrialDesign:
    """One trial: the serpenoid gait (amplitude, frequency, phase step, bias: Eqs. 3 and 7), the joints powered off
    (free, the paper's failure) at its start, its duration."""

    failed_joints: tuple[int, ...] = ()
    amplitude_deg: float = 38.0
    frequency_deg_s: float = 140.0
    phase_step_deg: float = 40.0
    bias_deg: float = 0.0
    seconds: float = 10.0

    def gait(self) -> Gait:
        return Gait(
            amplitude_deg=self.amplitude_deg,
            frequency_deg_s=self.frequency_deg_s,
            phase_step_deg=self.phase_step_deg,
            bias_deg=self.bias_deg,
        )

    def case(self) -> Case:
        return Case(list(self.failed_joints), 1, bias_deg=self.bias_deg, gait=self.gait(), seconds=self.seconds)

    def stop(self) -> Stop:
        return Stop(line_x_m=None, revolutions=None, time_limit_s=self.seconds)

    def scenario(self) -> Scenario:
        """What to set on the robot: the gait, the joints powered off at t = 0, the duration."""
        return Scenario(gait=self.gait(), failures=[Failure(joint=j) for j in self.failed_joints], start=Start(),
                        stop=self.stop())  # fmt: skip

    def label(self) -> str:
        failed = "+".join(f"J{j}" for j in self.failed_joints) or "no failure"
        return (
            f"{failed}, A {self.amplitude_deg:.0f} deg, {self.frequency_deg_s:.0f} deg/s, phase step "
            f"{self.phase_step_deg:.0f} deg, bias {self.bias_deg:+.1f} deg, {self.seconds:.0f} s"
        )


def joint_speed_deg_s(design: TrialDesign) -> float:
    """The gait's peak joint speed, A omega (Eq. 3)."""
    return math.radians(design.amplitude_deg) * design.frequency_deg_s


def infeasible(design: TrialDesign, lab: Lab) -> str | None:
    """Why the robot or the lab cannot run `design` before it is simulated, or None: a failure the lab cannot
    induce, joints past their +-38 deg limits (amplitude + |bias|), faster than the servos' 140 deg/s, a duration
    out of the lab's range."""
    if list(design.failed_joints) not in [list(f) for f in lab.failures]:
        return f"the lab cannot power off {list(design.failed_joints)}"
    if design.amplitude_deg + abs(design.bias_deg) > JOINT_LIMIT_DEG + 1e-9:
        return f"amplitude + |bias| {design.amplitude_deg + abs(design.bias_deg):.1f} deg past the joints' limit"
    if joint_speed_deg_s(design) > SERVO_SPEED_LIMIT_DEG_S + 1e-9:
        return f"{joint_speed_deg_s(design):.0f} deg/s of joint speed; the servos reach {SERVO_SPEED_LIMIT_DEG_S:.0f}"
    if not lab.min_seconds <= design.seconds <= lab.max_seconds:
        return f"{design.seconds:g} s outside the lab's {lab.min_seconds:g}-{lab.max_seconds:g} s"
    return None


def off_the_floor(t: np.ndarray, xy: np.ndarray, yaw_rate: np.ndarray, lab: Lab) -> str | None:
    """Why a simulated head path (at times t, N x 2, from the start at the origin heading +x) and its yaw rate
    cannot be run: off the lab's floor, or turning tighter than RC1's 0.6 m (its mean speed over its mean yaw
    rate); else None. Frames the camera did not see (NaN) are left out."""
    seen = ~np.isnan(xy).any(axis=1)
    t, xy = t[seen], xy[seen]
    (x0, x1), (y0, y1) = lab.floor_x_m, lab.floor_y_m
    if not (np.all((x0 <= xy[:, 0]) & (xy[:, 0] <= x1)) and np.all((y0 <= xy[:, 1]) & (xy[:, 1] <= y1))):
        return "the head leaves the floor"
    speed = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))) / max(float(t[-1] - t[0]), 1e-9)
    turning = abs(float(np.mean(yaw_rate)))
    if speed < MIN_TURNING_RADIUS_M * turning:
        return f"a {speed / turning:.2f} m turning radius, tighter than RC1's {MIN_TURNING_RADIUS_M} m"
    return None


def sampled_designs(lab: Lab, count: int, rng: np.random.Generator) -> list[TrialDesign]:
    """`count` feasible designs drawn over the lab's failures, amplitudes 15-38 deg, frequencies up to the servos'
    speed and at most MAX_FREQUENCY_DEG_S, phase steps 20-60 deg, biases within the joints' limit (both ways),
    durations in the lab's range."""
    out: list[TrialDesign] = []
    while len(out) < count:
        amplitude = float(rng.uniform(15.0, JOINT_LIMIT_DEG))
        fastest = min(SERVO_SPEED_LIMIT_DEG_S / math.radians(amplitude), MAX_FREQUENCY_DEG_S)
        design = TrialDesign(
            failed_joints=tuple(lab.failures[int(rng.integers(len(lab.failures)))]),
            amplitude_deg=round(amplitude, 1),
            frequency_deg_s=round(float(rng.uniform(0.4, 1.0) * fastest), 0),
            phase_step_deg=round(float(rng.uniform(20.0, 60.0)), 0),
            bias_deg=round(float(rng.uniform(-1.0, 1.0) * min(6.0, JOINT_LIMIT_DEG - amplitude)), 1),
            seconds=round(float(rng.uniform(lab.min_seconds, lab.max_seconds)), 0),
        )
        if infeasible(design, lab) is None:
            out.append(design)
    return out
