"""Draws one Panda-sorter state with MuJoCo's own renderer (outside jit, on the CPU; see panda/render.py)."""

import copy

import mujoco
import numpy as np

from jaxarm.envs.base import EnvState
from jaxarm.envs.panda.render import render_qpos
from jaxarm.envs.panda_sort.env import PandaSort, object_geom_sizes
from jaxarm.envs.panda_sort.layout import SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE

_VISIBLE_GEOMS = {SHAPE_CUBE: ("box",), SHAPE_CYLINDER: ("cylinder",), SHAPE_SPHERE: ("sphere",)}


def _dress_objects(
    model: mujoco.MjModel, env: PandaSort, shape: np.ndarray, size: np.ndarray, colour: np.ndarray
) -> None:
    """Sets the object geoms of `model` (a copy) to this episode's sizes, and shows only the drawn shape."""
    sizes = np.asarray(object_geom_sizes(shape, size))
    for slot in range(env.objects_count):
        for geom_id, geom_size in zip(env.ids.object_geom[slot], sizes[slot], strict=True):
            model.geom_size[geom_id] = geom_size
        cylinder = env.ids.object_visual[slot]
        model.geom_size[cylinder] = [size[slot], size[slot], 0.0]
        named = dict(zip(("box", "box45", "sphere", "cylinder"), [*env.ids.object_geom[slot], cylinder], strict=True))
        for name, geom_id in named.items():
            alpha = 1.0 if name in _VISIBLE_GEOMS[int(shape[slot])] else 0.0
            model.geom_rgba[geom_id] = [*colour[slot], alpha]


def render_frame(
    env: PandaSort, state: EnvState, height: int = 240, width: int = 320, camera: str = "front"
) -> np.ndarray:
    """A non-batched EnvState of `env` -> [height, width, 3] uint8 RGB frame."""
    sim = state.sim
    model = copy.copy(env.mj_model)  # sizes and colours change per episode; the env's model stays as built
    _dress_objects(model, env, np.asarray(sim.shape), np.asarray(sim.size), np.asarray(sim.colour))
    return render_qpos(model, np.asarray(sim.qpos), height, width, camera)
