"""The RC1 MultibodyPlant: models/rc1.sdf plus the planar base joint that SDFormat cannot express."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import PlanarJoint

from .config import NUM_JOINTS, REPO_ROOT
from .kinematics import ChainGeometry

MODEL_PATH = REPO_ROOT / "models" / "rc1.sdf"
NUM_MODULES = NUM_JOINTS + 1
STOP_BACKSTOP_DEG = 90.0  # two modules side by side: where a joint past its compliant stop meets a rigid one


def with_backstops(lower, upper, joints) -> tuple:
    """The joint limits (rad, (13,) each) with each of `joints` (1-based; effects.stop_backstops: a compliant stop
    in place of their limit) at +-STOP_BACKSTOP_DEG."""
    lower, upper = np.array(lower, dtype=float), np.array(upper, dtype=float)
    for joint in joints:
        lower[joint - 1], upper[joint - 1] = -math.radians(STOP_BACKSTOP_DEG), math.radians(STOP_BACKSTOP_DEG)
    return lower, upper


@dataclasses.dataclass(frozen=True)
class RC1Plant:
    plant: object  # MultibodyPlant
    scene_graph: object
    model_instance: object
    base_joint: object  # PlanarJoint: x, y, yaw of module_1 (the head) in the world
    joints: tuple  # RevoluteJoint joint_1 .. joint_13
    geometry: ChainGeometry
    effort_limit: np.ndarray  # (13,) N m, from the SDF


def add_rc1_plant(builder, *, time_step: float, model_path=MODEL_PATH, backstops=()) -> RC1Plant:
    """Add the discrete (SAP) plant of RC1, moving in the world's horizontal plane.

    A discrete plant enforces the joint limits (+-38 deg) as constraints: this is the restoring
    torque at the limits of paper section 3, and it keeps a failed joint inside them. The joints in
    `backstops` (1-based; effects.stop_backstops: a compliant stop in place of their limit) get
    with_backstops' wider limits, which a Drake plant takes only before it is finalized.
    """
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(time_step=time_step, discrete_contact_approximation="sap"), builder
    )
    (instance,) = Parser(plant).AddModels(str(model_path))
    # The SDF's effort limit is the servos' power (servo.py clamps their torque at it, or at a replay's own
    # cap); a plant clamp too would silently cut a replay's stiffer servos to RC1's 1.19 N m.
    actuators = [plant.get_joint_actuator(a) for a in plant.GetJointActuatorIndices()]
    effort = np.array([a.effort_limit() for a in actuators])
    for actuator in actuators:
        actuator.set_effort_limit(np.inf)
    head = plant.GetBodyByName("module_1", instance)
    base = plant.AddJoint(PlanarJoint("base", plant.world_frame(), head.body_frame(), np.zeros(3)))
    if backstops:
        limited = [plant.GetJointByName(f"joint_{i}", instance) for i in range(1, NUM_JOINTS + 1)]
        lower, upper = with_backstops(
            [j.position_lower_limits()[0] for j in limited], [j.position_upper_limits()[0] for j in limited], backstops
        )
        for i in backstops:
            limited[i - 1].set_position_limits([lower[i - 1]], [upper[i - 1]])
    plant.Finalize()
    plant.set_name("rc1_plant")
    joints = tuple(plant.GetJointByName(f"joint_{i}", instance) for i in range(1, NUM_JOINTS + 1))
    # The kinematics kernels assume this coordinate order; fail loudly if Drake ever changes it.
    assert base.position_start() == 0 and base.velocity_start() == 0
    assert [j.position_start() for j in joints] == list(range(3, 3 + NUM_JOINTS))
    return RC1Plant(
        plant=plant,
        scene_graph=scene_graph,
        model_instance=instance,
        base_joint=base,
        joints=joints,
        geometry=chain_geometry(plant, instance),
        effort_limit=effort,
    )


def chain_geometry(plant, instance) -> ChainGeometry:
    """Joint and wheel locations, masses and yaw inertias, read from the finalized plant."""
    context = plant.CreateDefaultContext()

    def planar(frame):
        X = frame.GetFixedPoseInBodyFrame()
        yaw = np.arctan2(X.rotation().matrix()[1, 0], X.rotation().matrix()[0, 0])
        return complex(*X.translation()[:2]), yaw

    j_parent, j_child = [], []
    for i in range(1, NUM_JOINTS + 1):
        joint = plant.GetJointByName(f"joint_{i}", instance)
        j_parent.append(planar(joint.frame_on_parent())[0])
        j_child.append(planar(joint.frame_on_child())[0])
    wheel_module, wheel_offset, wheel_yaw = [], [], []
    for k in range(1, NUM_MODULES + 1):
        if plant.HasFrameNamed(f"wheel_{k}", instance):
            xy, yaw = planar(plant.GetFrameByName(f"wheel_{k}", instance))
            wheel_module.append(k - 1)
            wheel_offset.append(xy)
            wheel_yaw.append(yaw)
    bodies = [plant.GetBodyByName(f"module_{k}", instance) for k in range(1, NUM_MODULES + 1)]
    mass = np.array([b.get_mass(context) for b in bodies])
    izz = np.array([b.CalcSpatialInertiaInBodyFrame(context).CalcRotationalInertia().get_moments()[2] for b in bodies])
    return ChainGeometry(
        joint_in_parent=np.array(j_parent),
        joint_in_child=np.array(j_child),
        wheel_module=np.array(wheel_module),
        wheel_offset=np.array(wheel_offset),
        wheel_yaw=np.array(wheel_yaw),
        module_mass=mass,
        module_yaw_inertia=izz,
    )


def module_inertias(plant, context) -> np.ndarray:
    """(14, 4): each module's mass (kg), yaw inertia about its centre of mass (kg m^2) and centre of mass (x, y, m)
    in its frame, as the plant holds them in `context` (a payload included): what the step's O(n) solve takes."""
    instance = plant.GetModelInstanceByName("rc1")
    rows = []
    for k in range(1, NUM_MODULES + 1):
        inertia = plant.GetBodyByName(f"module_{k}", instance).CalcSpatialInertiaInBodyFrame(context)
        com = inertia.get_com()
        central = inertia.Shift(com).CalcRotationalInertia().get_moments()[2]
        rows.append([inertia.get_mass(), central, com[0], com[1]])
    return np.array(rows)


def set_payload(plant, plant_context, module: int, kg: float) -> None:
    """Give module `module` (1..14; 0: none) an extra point mass `kg` at its centre, the others their SDF
    inertia. A point mass at the centre of mass adds mass but no rotational inertia about it."""
    from pydrake.multibody.tree import SpatialInertia

    instance = plant.GetModelInstanceByName("rc1")
    for k in range(1, NUM_MODULES + 1):
        body = plant.GetBodyByName(f"module_{k}", instance)
        base = body.default_spatial_inertia()
        extra = kg if k == module else 0.0
        central = base.CalcRotationalInertia()  # about the module's centre, which is its mass centre
        body.SetSpatialInertiaInBodyFrame(
            plant_context, SpatialInertia.MakeFromCentralInertia(base.get_mass() + extra, base.get_com(), central)
        )
