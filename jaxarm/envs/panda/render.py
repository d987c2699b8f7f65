"""Draws a MuJoCo scene at given joint positions with MuJoCo's own renderer (outside jit, on the CPU).

Headless machines need an offscreen GL: set MUJOCO_GL=osmesa (apt package libosmesa6) or MUJOCO_GL=egl
(libegl1 and a GPU driver, or Mesa's software EGL) before mujoco is imported.
"""

import mujoco
import numpy as np


def render_qpos(model: mujoco.MjModel, qpos: np.ndarray, height: int, width: int, camera: str) -> np.ndarray:
    """`model` posed at `qpos` [nq] -> [height, width, 3] uint8 RGB frame seen from `camera`."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, height=height, width=width) as renderer:
        renderer.update_scene(data, camera=camera)
        return renderer.render()
