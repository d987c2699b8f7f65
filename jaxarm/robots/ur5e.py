"""The Universal Robots UR5e with a two-finger gripper, declared once: `UR5E`.

Its model (`assets/ur5e/ur5e.xml`) is jaxarm's, on MuJoCo Menagerie's link frames; `assets/ur5e/menagerie/` holds
menagerie's UR5e for transfer tests (its README says what changed). Limits: Universal Robots' UR5e datasheet gives
every joint 180°/s and ±360° (the elbow's travel is kept to ±180°, as menagerie's, where the forearm clears the
upper arm) and the user manual's joint torques 150 N·m (base, shoulder, elbow) and 28 N·m (wrists), which are the
model's forceranges. UR publishes no acceleration limit (its controller limits torque): 10 rad/s² is the one
Universal Robots' own MoveIt configuration (ur_moveit_config, joint_limits.yaml) plans with; the jerk, as the
Panda's, is what reaches that acceleration in 2 ms (UR's 500 Hz servo period). Identified dynamics
(`identified_links`): the inertials of Universal Robots' URDF (ros-industrial universal_robot, ur_e_description,
BSD-3-Clause) in menagerie's frames; UR publishes no joint friction, so the model's own (damping 1 N·m·s/rad, no
Coulomb friction) stays.
"""

from pathlib import Path

import numpy as np

from jaxarm.robots.description import JointLimits, LinkDynamics, RobotDescription, frozen_array

ASSETS = Path(__file__).parent / "assets" / "ur5e"
_ARM_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
_NO_FRICTION = {"damping": 1.0, "frictionloss": 0.0}
_WRIST_INERTIA = (0.0025599, 0.0025599, 0.0021942, 0.0, 0.0, 0.0)
_UR_LINKS = (
    LinkDynamics(3.7, (0.0, 0.0, 0.0), (0.0102675, 0.0102675, 0.00666, 0.0, 0.0, 0.0), **_NO_FRICTION),
    LinkDynamics(8.393, (0.0, 0.0, 0.2125), (0.133886, 0.133886, 0.0151074, 0.0, 0.0, 0.0), **_NO_FRICTION),
    LinkDynamics(2.275, (0.0, 0.0, 0.196), (0.0311796, 0.0311796, 0.004095, 0.0, 0.0, 0.0), **_NO_FRICTION),
    LinkDynamics(1.219, (0.0, 0.127, 0.0), _WRIST_INERTIA, **_NO_FRICTION),
    LinkDynamics(1.219, (0.0, 0.0, 0.1), _WRIST_INERTIA, **_NO_FRICTION),
    # The URDF's principal axes turned a quarter about z into the link's frame.
    LinkDynamics(0.1889, (0.0, 0.0771683, 0.0), (9.90863e-05, 0.000132134, 9.90863e-05, 0.0, 0.0, 0.0), **_NO_FRICTION),
)
"""The UR5e's links from the shoulder to wrist 3, in joint order: each is the body its joint moves."""
_ACCELERATION = 10.0
_SERVO_PERIOD = 0.002

UR5E = RobotDescription(
    name="ur5e",
    model_xml=ASSETS / "ur5e.xml",
    menagerie_xml=ASSETS / "menagerie" / "ur5e.xml",
    # Menagerie's ur5e.xml sets no timestep: MuJoCo's default.
    menagerie_timestep=0.002,
    arm_joints=_ARM_JOINTS,
    arm_actuators=("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"),
    finger_joints=("finger_left", "finger_right"),
    finger_drives=(("finger_left", "finger_right"),),
    finger_open=0.0425,
    tcp_site="tcp",
    hand_body="hand",
    pad_above_tcp=0.0,
    # Menagerie's home keyframe with the wrist turned a quarter more: tool centre 0.34 m above the table, pointing
    # down, its x axis along the world's (the Panda's home orientation).
    home_qpos=frozen_array([-np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, -np.pi / 2]),
    joint_limits=JointLimits(
        speed=frozen_array(np.full(6, np.pi)),
        acceleration=frozen_array(np.full(6, _ACCELERATION)),
        jerk=frozen_array(np.full(6, _ACCELERATION / _SERVO_PERIOD)),
    ),
    identified_links=_UR_LINKS,
    ik_damping=0.05,
    ik_posture_gain=0.05,
    home_noise=0.02,
)
