"""`RobotDescription`: what makes a robot arm, declared once per robot (`jaxarm.robots.panda`) and read by the envs,
their IK and the deployment loop. Imports numpy alone: the JAX-free deployment package reads it on the robot's
computer.
"""

import dataclasses
from pathlib import Path

import numpy as np


def frozen_array(values, dtype=np.float32) -> np.ndarray:
    """`values` as a read-only array: a description's arrays are shared by every env and loop that reads them."""
    array = np.array(values, dtype)
    array.flags.writeable = False
    return array


# eq=False: numpy fields compare element-wise and do not hash, so a generated __eq__ and __hash__ would fail; these
# compare and hash by identity.
@dataclasses.dataclass(frozen=True, eq=False)
class JointLimits:
    """The arm joints' motion limits (each [J], float32), which the model's servos do not enforce: the envs and the
    deployment loop keep their targets' path within them. Force limits are the model's actuator forceranges.

    Attributes:
      speed: rad/s.
      acceleration: rad/s².
      jerk: rad/s³, what a 1 kHz servo stream keeps within (`jaxarm.deploy.stream`); a 25 Hz tick's targets are not
        held to it.
    """

    speed: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray


@dataclasses.dataclass(frozen=True)
class LinkDynamics:
    """One moving link of the arm, in the frame of its body, and the friction of the joint that turns it.

    Attributes:
      mass: kg.
      com: [3] centre of mass, m.
      inertia: [6] inertia tensor about the centre of mass, (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) as MJCF's
        `fullinertia`, kg·m².
      damping: viscous friction of the joint, N·m·s/rad.
      frictionloss: Coulomb friction of the joint, N·m.
    """

    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]
    damping: float
    frictionloss: float


@dataclasses.dataclass(frozen=True, eq=False)
class RobotDescription:
    """A robot arm with a parallel gripper: its model files, names, postures, limits and control defaults.

    Attributes:
      name: the robot's name in the registry (`jaxarm.robots.robot`).
      model_xml: jaxarm's MJCF include file of the robot, which a task's scene takes in (`scene_spec` in
        `jaxarm.envs.panda.robot`).
      menagerie_xml: the same robot from MuJoCo Menagerie with `model_xml`'s names (a robot jaxarm did not write, for
        transfer tests).
      menagerie_timestep: the physics timestep `menagerie_xml` is simulated at (seconds).
      arm_joints: [J] the arm's joint names, base to wrist (J: the arm's joint count, 7 for the Panda, 6 for the
        UR5e; a model lists the arm's joints first, then the fingers', and its actuators likewise).
      arm_actuators: [J] the names of the arm joints' position servos, in `arm_joints` order.
      finger_joints: the gripper's finger joint names.
      finger_drives: the gripper drives a model of the robot may have, each a tuple of actuator names: one position
        servo per finger (jaxarm's) or one for all (menagerie's).
      finger_open: finger joint travel when fully open (each finger; metres).
      tcp_site: the site at the tool centre point (between the finger pads).
      hand_body: the body the gripper is mounted on; the tool centre's Jacobian is taken on it.
      pad_above_tcp: how far the finger pads' centre is above the tool centre (metres).
      home_qpos: [J] float32, the arm's home posture, from which its IK starts.
      joint_limits: the arm joints' motion limits (`JointLimits`).
      identified_links: [J] the arm's identified link inertials and joint friction, in `arm_joints` order: the
        dynamics an env may be built with in place of the model's own (`dynamics=identified`,
        `jaxarm.envs.panda.dynamics`).
      ik_damping: default damping λ of the damped-least-squares IK (metres-radians).
      ik_posture_gain: default null-space pull of the arm towards its start posture per step (fraction of the
        error).
      home_noise: default half-width of the uniform noise on the arm's initial joint angles (radians).
    """

    name: str
    model_xml: Path
    menagerie_xml: Path
    menagerie_timestep: float
    arm_joints: tuple[str, ...]
    arm_actuators: tuple[str, ...]
    finger_joints: tuple[str, ...]
    finger_drives: tuple[tuple[str, ...], ...]
    finger_open: float
    tcp_site: str
    hand_body: str
    pad_above_tcp: float
    home_qpos: np.ndarray
    joint_limits: JointLimits
    identified_links: tuple[LinkDynamics, ...]
    ik_damping: float
    ik_posture_gain: float
    home_noise: float
