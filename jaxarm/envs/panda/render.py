"""Draws a MuJoCo scene at given joint positions with MuJoCo's own renderer (outside jit, on the CPU).

Headless machines need an offscreen GL: set MUJOCO_GL=osmesa (apt package libosmesa6) or MUJOCO_GL=egl
(libegl1 and a GPU driver, or Mesa's software EGL) before mujoco is imported.
"""

import weakref

import mujoco
import numpy as np


class Drawing:
    """A model to draw, its data, and a renderer per frame size, built once and reused for every frame.

    Attributes:
      model: the model drawn; callers may change its geometry (sizes, colours, positions) between frames.
    """

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self.data = mujoco.MjData(model)
        self.renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        # Closed while the interpreter still runs: closed at its teardown, a renderer prints a TypeError.
        weakref.finalize(self, _close_all, self.renderers)

    def render(self, qpos: np.ndarray, height: int, width: int, camera: str) -> np.ndarray:
        """`model` posed at `qpos` [nq] -> [height, width, 3] uint8 RGB frame seen from `camera`."""
        self.data.qpos[:] = qpos
        mujoco.mj_forward(self.model, self.data)
        size = (height, width)
        if size not in self.renderers:
            self.renderers[size] = mujoco.Renderer(self.model, height=height, width=width)
        renderer = self.renderers[size]
        renderer.update_scene(self.data, camera=camera)
        return renderer.render()


def _close_all(renderers: dict[tuple[int, int], mujoco.Renderer]) -> None:
    for renderer in renderers.values():
        renderer.close()
