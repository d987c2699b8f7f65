"""The Franka Emika Panda, declared once: `PANDA`, read by every Panda task, its IK and the deployment loop.

Its limits are Franka's datasheet's. Its identified dynamics (`identified_links`): dm-robotics-panda 0.4.8
(github.com/JeanElsner/dm_robotics_panda, Apache-2.0), file src/dm_robotics/panda/assets/panda/panda.xml, which ships
Franka's franka_ros model (Apache-2.0, its NOTICE). Its link frames are panda.xml's (the same modified-DH frames), so
the numbers apply as they stand. Its inertials are those Gaz et al. identified ("Dynamic Identification of the Franka
Emika Panda Robot With Retrieval of Feasible Parameters Using Penalty-Based Optimization", IEEE RA-L 2019,
supplementary material, Tables VIII and IX); its friction is one viscous and one Coulomb coefficient per joint. Two
entries depart from that file, each noted where it stands.
"""

from pathlib import Path

from jaxarm.robots.description import JointLimits, LinkDynamics, RobotDescription, frozen_array

ASSETS = Path(__file__).parents[1] / "envs" / "panda" / "assets"
_ARM_JOINTS = tuple(f"joint{k}" for k in range(1, 8))

_FRANKA_LINKS = (
    LinkDynamics(
        4.970684,
        (3.875e-3, 2.081e-3, -4.762e-2),
        (7.0337e-1, 7.0661e-1, 9.117e-3, -1.39e-4, 6.772e-3, 1.9169e-2),
        damping=0.0665,
        frictionloss=0.2450,
    ),
    LinkDynamics(
        0.646926,
        (-3.141e-3, -2.872e-2, 3.495e-3),
        (7.962e-3, 2.811e-2, 2.5995e-2, -3.925e-3, 1.0254e-2, 7.04e-4),
        damping=0.1987,
        frictionloss=0.1523,
    ),
    LinkDynamics(
        3.228604,
        (2.7518e-2, 3.9252e-2, -6.6502e-2),
        (3.7242e-2, 3.6155e-2, 1.083e-2, -4.761e-3, -1.1396e-2, -1.2805e-2),
        damping=0.0399,
        frictionloss=0.1827,
    ),
    LinkDynamics(
        3.587895,
        (-5.317e-2, 1.04419e-1, 2.7454e-2),
        (2.5853e-2, 1.9552e-2, 2.8323e-2, 7.796e-3, -1.332e-3, 8.641e-3),
        damping=0.2257,
        frictionloss=0.3591,
    ),
    LinkDynamics(
        1.225946,
        (-1.1953e-2, 4.1065e-2, -3.8437e-2),
        (3.5549e-2, 2.9474e-2, 8.627e-3, -2.117e-3, -4.037e-3, 2.29e-4),
        damping=0.1023,
        frictionloss=0.2669,
    ),
    LinkDynamics(
        1.666555,
        (6.0149e-2, -1.4117e-2, -1.0517e-2),
        (1.964e-3, 4.354e-3, 5.433e-3, 1.09e-4, -1.158e-3, 3.41e-4),
        # The source's -0.0132 is the identification's estimate of a coefficient that is zero within its
        # accuracy; negative damping would feed energy into the joint.
        damping=0.0,
        frictionloss=0.1658,
    ),
    LinkDynamics(
        0.735522,
        (1.0517e-2, -4.252e-3, 6.1597e-2),
        (1.2516e-2, 1.0027e-2, 4.815e-3, -4.28e-4, -1.196e-3, -7.41e-4),
        damping=0.0638,
        # The source's 1.2109 reads as a slip for 0.2109: Gaz et al.'s smooth friction model spans only 0.565 N·m
        # in all at joint 7 (phi_1 of their supplementary Table I), and every other joint's Coulomb friction here
        # is below 0.36 N·m.
        frictionloss=0.2109,
    ),
)
"""Franka's arm links 1 to 7, in joint order: each is the body its joint moves."""

PANDA = RobotDescription(
    name="panda",
    model_xml=ASSETS / "panda.xml",
    menagerie_xml=ASSETS / "menagerie" / "panda.xml",
    # Menagerie's panda.xml sets no timestep, so MuJoCo's default. Its wrist servos (kp 2000, kv 200, clamped at
    # 12 N·m) need it: at the scenes' 0.01 s a clamped servo's damping acts explicitly (200 · 0.01 / ~0.11 kg·m²,
    # beyond the stable 2), and in MuJoCo C the wrist chattered between its force limits, ending a 0.1 rad target
    # step at 56% after 0.4 s (at 0.002 s: 98%, as jaxarm's wrist at 0.01 s).
    menagerie_timestep=0.002,
    arm_joints=_ARM_JOINTS,
    # jaxarm's panda.xml names each arm servo after its joint; so does its menagerie copy.
    arm_actuators=_ARM_JOINTS,
    finger_joints=("finger_left", "finger_right"),
    finger_drives=(("finger_left", "finger_right"), ("fingers",)),
    finger_open=0.04,
    tcp_site="tcp",
    hand_body="hand",
    pad_above_tcp=0.003,
    # Franka's "ready" pose: tool centre 0.49 m above the table, pointing down.
    home_qpos=frozen_array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]),
    joint_limits=JointLimits(
        speed=frozen_array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]),
        acceleration=frozen_array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),
        jerk=frozen_array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]),
    ),
    identified_links=_FRANKA_LINKS,
    ik_damping=0.05,
    ik_posture_gain=0.05,
    home_noise=0.02,
)
