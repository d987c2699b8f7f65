"""The planar N-link reaching arm."""

from jaxarm.envs.arm2d.arm import GOAL_FIXED, GOAL_UNIFORM_REACHABLE, GOAL_UNIFORM_WORLD, Arm2dParams, Arm2dSim
from jaxarm.envs.arm2d.env import Arm2d, Arm2dInfo

__all__ = [
    "GOAL_FIXED",
    "GOAL_UNIFORM_REACHABLE",
    "GOAL_UNIFORM_WORLD",
    "Arm2d",
    "Arm2dInfo",
    "Arm2dParams",
    "Arm2dSim",
]
