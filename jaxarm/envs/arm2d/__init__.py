"""The planar N-link reaching arm."""

from jaxarm.envs.arm2d.env import (
    GOAL_FIXED,
    GOAL_UNIFORM_REACHABLE,
    GOAL_UNIFORM_WORLD,
    Arm2d,
    Arm2dInfo,
    Arm2dParams,
    Arm2dSim,
)

__all__ = [
    "GOAL_FIXED",
    "GOAL_UNIFORM_REACHABLE",
    "GOAL_UNIFORM_WORLD",
    "Arm2d",
    "Arm2dInfo",
    "Arm2dParams",
    "Arm2dSim",
]
