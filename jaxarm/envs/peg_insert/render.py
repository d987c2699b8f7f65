"""Draws one peg-insertion state with MuJoCo's own renderer (outside jit, on the CPU; see panda/render.py)."""

import copy

import numpy as np

from jaxarm.envs.base import EnvState
from jaxarm.envs.panda.render import render_qpos
from jaxarm.envs.peg_insert.env import PegInsert
from jaxarm.envs.peg_insert.model import hole_walls
from jaxarm.envs.peg_insert.params import PegInsertParams


def render_frame(
    env: PegInsert, state: EnvState, params: PegInsertParams, height: int = 240, width: int = 320, camera: str = "front"
) -> np.ndarray:
    """A non-batched EnvState of `env` -> [height, width, 3] uint8 RGB frame, the hole where it was."""
    model = copy.copy(env.mj_model)  # the hole moves and resizes per episode; the env's model stays as built
    centres, halves = (np.asarray(array) for array in hole_walls(params.clearance))
    model.geom_pos[env.ids.wall_geoms] = centres
    model.geom_size[env.ids.wall_geoms] = halves
    model.body_pos[env.ids.block_body, :2] = np.asarray(state.sim.hole)
    return render_qpos(model, np.asarray(state.sim.qpos), height, width, camera)
