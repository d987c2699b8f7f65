"""The Panda sorter: a Franka Panda sorting cubes, cylinders and spheres into shape bins, in MJX."""

from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.panda_sort.env import MODE_EE, MODE_JOINT, PandaSort
from jaxarm.envs.panda_sort.layout import SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_NAMES, SHAPE_SPHERE, Layout, make_layout
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.envs.panda_sort.reward import (
    IN_CORRECT_BIN,
    IN_PLAY,
    IN_WRONG_BIN,
    ON_FLOOR,
    PandaSortInfo,
    RewardTerms,
)
from jaxarm.envs.panda_sort.sim import PandaSortSim

__all__ = [
    "CONTROL_DT",
    "IN_CORRECT_BIN",
    "IN_PLAY",
    "IN_WRONG_BIN",
    "MODE_EE",
    "MODE_JOINT",
    "ON_FLOOR",
    "SHAPE_CUBE",
    "SHAPE_CYLINDER",
    "SHAPE_NAMES",
    "SHAPE_SPHERE",
    "Layout",
    "PandaSort",
    "PandaSortInfo",
    "PandaSortParams",
    "PandaSortSim",
    "RewardTerms",
    "make_layout",
]
