"""A 6-joint arm for the deployment package's tests (a UR5e has 6): its joint limits, a description of it and a
small stock-MuJoCo scene with its names, so that the loop, the servo stream, the wire and stock MuJoCo run with J = 6
as well as the Panda's 7."""

import dataclasses

import mujoco
import numpy as np

from jaxarm.robots import PANDA
from jaxarm.robots.description import JointLimits, frozen_array

JOINTS = 6

LIMITS = JointLimits(
    speed=frozen_array(np.full(JOINTS, 3.0)),
    acceleration=frozen_array(np.full(JOINTS, 10.0)),
    jerk=frozen_array(np.full(JOINTS, 5000.0)),
)
"""Round numbers, each joint's alike, unlike any of the Panda's: a piece that reads the Panda's shows."""

DESCRIPTION = dataclasses.replace(
    PANDA,
    name="six",
    arm_joints=PANDA.arm_joints[:JOINTS],
    arm_actuators=PANDA.arm_actuators[:JOINTS],
    home_qpos=frozen_array(np.zeros(JOINTS)),
    joint_limits=LIMITS,
    identified_links=PANDA.identified_links[:JOINTS],
)
"""The Panda's description cut to its first 6 joints, with `LIMITS`: the names `scene` is built with."""


def scene() -> mujoco.MjModel:
    """A chain of 6 hinged links ending in 2 sliding fingers, a position servo on each joint, named as `DESCRIPTION`
    (jaxarm's gripper: one servo per finger, commanded in metres). Contacts are off: the links only move."""
    links = "".join(
        f'<body pos="0 0 0.1"><joint name="{name}" axis="0 1 0"/><geom size="0.03"/>' for name in DESCRIPTION.arm_joints
    )
    fingers = "".join(
        f'<body><joint name="{name}" type="slide" axis="1 0 0" range="0 0.04"/><geom size="0.01"/></body>'
        for name in DESCRIPTION.finger_joints
    )
    arm_servos = "".join(f'<position name="{name}" joint="{name}" kp="100"/>' for name in DESCRIPTION.arm_actuators)
    finger_servos = "".join(
        f'<position name="{name}" joint="{name}" kp="100" ctrlrange="0 0.04"/>' for name in DESCRIPTION.finger_joints
    )
    xml = f"""<mujoco>
      <option timestep="0.002"><flag contact="disable"/></option>
      <default><joint damping="5"/></default>
      <worldbody>{links}{fingers}{"</body>" * JOINTS}</worldbody>
      <actuator>{arm_servos}{finger_servos}</actuator>
    </mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)
