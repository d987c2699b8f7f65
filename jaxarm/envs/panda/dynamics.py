"""The robot's own dynamics, as an option: its identified link inertials and joint friction (the Panda's: Franka's).

panda.xml's links carry masses rounded from Franka's but the inertia of their capsules (centre of mass on the
link axis), and every arm joint damping 1. `set_dynamics(spec, "identified", robot)` writes into a scene's MjSpec the
moving links' identified inertials (mass, centre of mass, full inertia tensor) and each arm joint's viscous
(`damping`) and Coulomb (`frictionloss`) friction, as the robot's description declares them (`identified_links`,
whose source `jaxarm.robots.panda` gives). It must change nothing else: geoms, kinematics, armature, actuators and
the hand stay the model's, so every task keeps its contacts, its IK and its servos.
"""

import mujoco

from jaxarm.robots import RobotDescription

NOMINAL = "nominal"
IDENTIFIED = "identified"
DYNAMICS = (NOMINAL, IDENTIFIED)
"""The dynamics an env may be built with: the robot's model file's own, or the identified ones of its description."""


def set_dynamics(spec: mujoco.MjSpec, dynamics: str, robot: RobotDescription) -> None:
    """Writes `dynamics` into `robot` in `spec` (in place): nothing for "nominal", its description's
    `identified_links` for "identified".

    Raises ValueError naming the valid choices for any other `dynamics`.
    """
    if dynamics not in DYNAMICS:
        raise ValueError(f"dynamics must be one of {', '.join(DYNAMICS)}, got {dynamics!r}")
    if dynamics == NOMINAL:
        return
    for name, link in zip(robot.arm_joints, robot.identified_links, strict=True):
        joint = spec.joint(name)
        # MuJoCo 4's joint damping is (linear, then polynomial terms); Franka's is the linear term.
        joint.damping = [link.damping, *joint.damping[1:]]
        joint.frictionloss = link.frictionloss
        body = joint.parent
        # An explicit inertial replaces the one the compiler would infer from the body's capsule.
        body.explicitinertial = True
        body.mass, body.ipos, body.fullinertia = link.mass, link.com, link.inertia
