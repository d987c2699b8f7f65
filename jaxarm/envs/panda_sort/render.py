"""Dresses a copy of the sorter's MjModel for drawing: this episode's object sizes, colours and shapes.

Outside jit, on the CPU; `ArmBase.render` draws the dressed model (panda/render.py). Imports no env module.
"""

import mujoco
import numpy as np

from jaxarm.envs.panda_sort.layout import SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE
from jaxarm.envs.panda_sort.model import ModelIds
from jaxarm.envs.panda_sort.objects import object_geom_sizes

_VISIBLE_GEOMS = {SHAPE_CUBE: ("box",), SHAPE_CYLINDER: ("cylinder",), SHAPE_SPHERE: ("sphere",)}


def dress_objects(
    model: mujoco.MjModel, ids: ModelIds, shape: np.ndarray, size: np.ndarray, colour: np.ndarray
) -> None:
    """Sets the object geoms of `model` (a copy) to [N] `shape`s and `size`s and [N, 3] `colour`s, showing
    only each slot's drawn shape."""
    sizes = np.asarray(object_geom_sizes(shape, size))
    for slot, (geoms, cylinder) in enumerate(zip(ids.object_geom, ids.object_visual, strict=True)):
        for geom_id, geom_size in zip(geoms, sizes[slot], strict=True):
            model.geom_size[geom_id] = geom_size
        model.geom_size[cylinder] = [size[slot], size[slot], 0.0]
        named = dict(zip(("box", "box45", "sphere", "cylinder"), [*geoms, cylinder], strict=True))
        for name, geom_id in named.items():
            alpha = 1.0 if name in _VISIBLE_GEOMS[int(shape[slot])] else 0.0
            model.geom_rgba[geom_id] = [*colour[slot], alpha]
