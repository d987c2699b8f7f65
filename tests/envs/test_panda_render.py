"""Panda drawing reuses one model copy and renderer: frames equal those of a renderer built for each frame."""

import copy

import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.panda.render import Drawing


@pytest.fixture(scope="module")
def model():
    import mujoco

    built = envs.make("peg_insert").mj_model
    try:
        mujoco.Renderer(built, 24, 32).close()
    except Exception as error:  # no GL platform here (mujoco.FatalError, or the loader's own error)
        pytest.skip(f"no offscreen GL (set MUJOCO_GL=egl or osmesa): {error}")
    return built


def test_a_reused_renderer_draws_what_a_fresh_one_draws(model):
    reused = Drawing(copy.copy(model))
    qpos = model.qpos0.copy()
    for size in (0.02, 0.05):
        reused.model.geom_size[:, 0] = np.maximum(model.geom_size[:, 0], size)
        frame = reused.render(qpos, 60, 80, "front")
        fresh = Drawing(copy.copy(reused.model))
        np.testing.assert_array_equal(frame, fresh.render(qpos, 60, 80, "front"))
        qpos = qpos + 0.1
    assert len(reused.renderers) == 1
