"""A deployable task's entry: what builds its controller from an env, its scene with another model of its robot, and
one of its episodes in stock MuJoCo through the deployment loop (`registry.DEPLOYABLES` lists the entries)."""

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from jaxarm.deploy.camera import SeesItself
from jaxarm.deploy.loop import DeploymentLoop
from jaxarm.deploy.mujoco_robot import MujocoRobot

Capture = Callable[[mujoco.MjData], None]
"""Called with the scene's state at an episode's start and after each tick (a video's frames)."""


@dataclasses.dataclass(frozen=True)
class Deployable:
    """One task the deployment loop runs.

    Attributes:
      env_class: the env whose instances the task is (wrapped ones too; state observations or cameras).
      controller: (env, params) -> the task's numpy controller, posing the arm in the env's own model (with its
        proprio part for a camera's policy).
      scene: (env, params, robot_xml) -> the env's scene with its robot's model `robot_xml` in place of jaxarm's (a
        cached model: copy it before editing).
      episode: (robot, loop, env, params, sim, capture, pose_bias) -> one episode from `sim` (the env's reset, as
        numpy arrays) on `robot` (the task's scene) through `loop`, scored from MuJoCo's state in numpy: its
        "success", "return" and "steps", and any of the task's own numbers ("placed": the sorter's fraction of
        objects placed). `pose_bias` [3] (m) is added to every position estimate the loop is given (the sorter's
        objects' centres; the peg's hole centre, x and y), as a miscalibrated camera would err all episode.
    """

    env_class: type
    controller: Callable[[Any, Any], SeesItself]
    scene: Callable[[Any, Any, Path], mujoco.MjModel]
    episode: Callable[[MujocoRobot, DeploymentLoop, Any, Any, Any, Capture, np.ndarray], dict]
