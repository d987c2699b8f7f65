"""Places the block of a copy of the peg-insertion MjModel for drawing: the hole where it was this episode, the block
and the table in their gray of the episode.

Outside jit, on the CPU; `ArmBase.render` draws the posed model (panda/render.py). Imports no env module.
"""

import mujoco
import numpy as np

from jaxarm.envs.peg_insert.model import PegIds, hole_walls


def place_block(model: mujoco.MjModel, ids: PegIds, hole: np.ndarray, clearance: np.ndarray) -> None:
    """Moves the block of `model` (a copy) to the hole's (x, y) `hole` [2] with walls at `clearance` []."""
    centres, halves = (np.asarray(array) for array in hole_walls(clearance))
    model.geom_pos[ids.wall_geoms] = centres
    model.geom_size[ids.wall_geoms] = halves
    model.body_pos[ids.block_body, :2] = hole


def paint_surfaces(model: mujoco.MjModel, ids: PegIds, surface_gray: np.ndarray) -> None:
    """Colours the block's boxes and the table of `model` (a copy) gray, at the episode's `surface_gray` [2] (the
    block's, the table's; 0-1), as the env's cameras see them."""
    model.geom_rgba[ids.block_geoms, :3] = surface_gray[0]
    model.geom_rgba[ids.table_geom, :3] = surface_gray[1]
