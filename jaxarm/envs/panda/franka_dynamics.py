"""The Panda's own dynamics, as an option: Franka's link inertials and the joints' identified friction.

panda.xml's links carry masses rounded from Franka's but the inertia of their capsules (centre of mass on the
link axis), and every arm joint damping 1. `set_dynamics(spec, "franka")` writes into a scene's MjSpec the seven
moving links' published inertials (mass, centre of mass, full inertia tensor) and each arm joint's viscous
(`damping`) and Coulomb (`frictionloss`) friction. It must change nothing else: geoms, kinematics, armature,
actuators and the hand stay panda.xml's, so every task keeps its contacts, its IK and its servos.

Source: dm-robotics-panda 0.4.8 (github.com/JeanElsner/dm_robotics_panda, Apache-2.0), file
src/dm_robotics/panda/assets/panda/panda.xml, which ships Franka's franka_ros model (Apache-2.0, its NOTICE). Its
link frames are panda.xml's (the same modified-DH frames), so the numbers apply as they stand. Its inertials are
those Gaz et al. identified ("Dynamic Identification of the Franka Emika Panda Robot With Retrieval of Feasible
Parameters Using Penalty-Based Optimization", IEEE RA-L 2019, supplementary material, Tables VIII and IX); its
friction is one viscous and one Coulomb coefficient per joint. Two entries depart from that file, each noted where
it stands in `FRANKA_LINKS`.
"""

import dataclasses

import mujoco

from jaxarm.envs.panda.robot import ARM_JOINTS

NOMINAL = "nominal"
FRANKA = "franka"
DYNAMICS = (NOMINAL, FRANKA)
"""The Panda dynamics an env may be built with: panda.xml's own, or Franka's (`FRANKA_LINKS`)."""


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


FRANKA_LINKS = (
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
"""The arm's links 1 to 7, in `ARM_JOINTS` order: each is the body its joint moves."""


def set_dynamics(spec: mujoco.MjSpec, dynamics: str) -> None:
    """Writes `dynamics` into the Panda of `spec` (in place): nothing for "nominal", `FRANKA_LINKS` for "franka".

    Raises ValueError naming the valid choices for any other `dynamics`.
    """
    if dynamics not in DYNAMICS:
        raise ValueError(f"dynamics must be one of {', '.join(DYNAMICS)}, got {dynamics!r}")
    if dynamics == NOMINAL:
        return
    for name, link in zip(ARM_JOINTS, FRANKA_LINKS, strict=True):
        joint = spec.joint(name)
        # MuJoCo 4's joint damping is (linear, then polynomial terms); Franka's is the linear term.
        joint.damping = [link.damping, *joint.damping[1:]]
        joint.frictionloss = link.frictionloss
        body = joint.parent
        # An explicit inertial replaces the one the compiler would infer from the body's capsule.
        body.explicitinertial = True
        body.mass, body.ipos, body.fullinertia = link.mass, link.com, link.inertia
