"""The robot arms jaxarm knows, each a `RobotDescription` declared once in its own module, by name.

Imports numpy alone, so the JAX-free deployment package reads the same descriptions as the envs.
"""

from jaxarm.robots.description import RobotDescription
from jaxarm.robots.panda import PANDA
from jaxarm.robots.ur5e import UR5E

ROBOTS = {robot.name: robot for robot in (PANDA, UR5E)}
"""Every robot description, by name."""


def robot(name: str) -> RobotDescription:
    """The description of robot `name`; raises ValueError naming the known robots for any other."""
    if name not in ROBOTS:
        raise ValueError(f"unknown robot {name!r}; known: {', '.join(sorted(ROBOTS))}")
    return ROBOTS[name]
