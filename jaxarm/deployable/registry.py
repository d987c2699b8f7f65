"""The tasks the deployment loop runs, one entry each: a new deployable task is its module and one line in
`DEPLOYABLES`."""

import mujoco

from jaxarm.deploy.camera import CameraController, CameraRenderer
from jaxarm.deploy.loop import Controller
from jaxarm.deployable import panda_sort, peg_insert
from jaxarm.deployable.base import Deployable
from jaxarm.export.numpy_policy import PROPRIO

DEPLOYABLES: tuple[Deployable, ...] = (panda_sort.DEPLOYABLE, peg_insert.DEPLOYABLE)


def find(env) -> Deployable | None:
    """The entry of `env` (or the env it wraps) if it is one of `DEPLOYABLES`' envs, with state observations or a
    camera's (`camera_controller`)."""
    env = getattr(env, "unwrapped", env)
    return next((listed for listed in DEPLOYABLES if isinstance(env, listed.env_class)), None)


def entry(env) -> Deployable:
    """`find(env)`; ValueError naming the envs the loop runs where it runs no task of `env`."""
    found = find(env)
    if found is None:
        env = getattr(env, "unwrapped", env)
        names = ", ".join(listed.env_class.__name__ for listed in DEPLOYABLES)
        raise ValueError(f"the deployment loop runs {names}, not {type(env).__name__}")
    return found


def runs(env) -> bool:
    """Whether the deployment loop runs `env` (or the env it wraps)."""
    return find(env) is not None


def controller(env, params) -> Controller:
    """The numpy controller of `env` (one the loop `runs`) with `params`, posing the arm in the env's own model,
    observing as its state mode does (a camera's env: `camera_controller`). ValueError for any other env."""
    return entry(env).controller(getattr(env, "unwrapped", env), params)


def camera_renderer(env, model: mujoco.MjModel) -> CameraRenderer:
    """MuJoCo's renderer of `env`'s camera image (its cameras by name, its resolution) in `model`, a robot's scene
    (`env` one the loop `runs`, with a pixel obs_mode)."""
    env = getattr(env, "unwrapped", env)
    return CameraRenderer(model, env.camera_names, env.resolution)


def camera_controller(env, params, renderer: CameraRenderer, data: mujoco.MjData) -> CameraController:
    """The controller of `env` (with a pixel obs_mode) observing as its policy reads: `renderer`'s image of the
    scene posed in `data` (a robot's, read at each tick), with the proprio part where `env` observes one."""
    parts = env.spec.observation_parts or {}
    task = entry(env).controller(getattr(env, "unwrapped", env), params)
    return CameraController(task, lambda: renderer.image(data), PROPRIO in parts)
