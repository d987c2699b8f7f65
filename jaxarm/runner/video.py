"""Videos of a policy: deterministic episodes played to their end and drawn frame by frame (outside jit).

GIF needs nothing more; mp4 needs imageio-ffmpeg (`pip install jaxarm[video]`, which brings its own ffmpeg).
Panda envs draw with MuJoCo's renderer, which needs an offscreen GL platform on a machine without a display:
`jaxarm.headless.GL_HINT`. `experiments.eval` tries it (`jaxarm.headless.gl_problem`) before it imports the
learners or builds anything, so a missing GL fails in seconds, not after the rollout's compilation (9.5 minutes for
a Panda env on a CPU).
"""

import operator
import pathlib
import warnings

import imageio.v2 as imageio
import jax
import numpy as np

from jaxarm.agents.common.evaluate import rollout_episodes
from jaxarm.envs.observation import with_camera_views
from jaxarm.headless import no_gl_message

FRAME_SECONDS = 0.04


class RenderError(RuntimeError):
    """The env cannot draw here (no GL platform) or the video cannot be written; the message says what to do."""


def episode_frames(env, env_params, trainer, state, key, episodes: int) -> list[np.ndarray]:
    """Frames of `episodes` deterministic episodes played one after another, each until it ends; a policy that
    sees has its camera's image beside each frame.

    The rollout is one compiled program taking the learner state as an argument (not baked in as constants), so
    the persistent compilation cache serves it to every later video of the same config.
    """
    max_steps = int(env_params.max_episode_steps)
    rollout = jax.jit(
        lambda learner, key: rollout_episodes(
            env, env_params, lambda obs: trainer.act(learner, obs), key, episodes, max_steps
        )
    )
    states = jax.device_get(rollout(state, key))
    frames = []
    try:
        for episode in range(episodes):
            length = int(states.episode.length[-1, episode])
            for step in range(length):
                state_now = jax.tree.map(operator.itemgetter((step, episode)), states)
                frames.append(with_camera_views(env.render(state_now, env_params), state_now.obs))
    except Exception as error:  # mujoco.FatalError and GL loaders' errors share no base class
        if "gl" in str(error).lower() or "display" in str(error).lower():
            raise RenderError(no_gl_message(error)) from None
        raise
    return frames


def write_video(path: pathlib.Path, frames: list[np.ndarray]) -> None:
    """Writes `frames` ([H, W, 3] uint8 each) as a GIF or an mp4, by `path`'s suffix."""
    if path.suffix == ".gif":
        imageio.mimsave(path, frames, duration=FRAME_SECONDS, loop=0)  # type: ignore[arg-type]
        return
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise RenderError("mp4 needs imageio-ffmpeg: pip install 'jaxarm[video]' (or write a .gif)") from None
    # ffmpeg runs as a child process; JAX's warning about forking a threaded process does not apply to an exec.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
        # macro_block_size=1: imageio would otherwise pad frames to multiples of 16 pixels (and warn).
        with imageio.get_writer(path, fps=round(1 / FRAME_SECONDS), macro_block_size=1) as writer:
            for frame in frames:
                writer.append_data(np.asarray(frame))  # type: ignore[attr-defined]
