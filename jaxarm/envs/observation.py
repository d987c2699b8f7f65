"""Observation modes an env with a camera offers, and the dict observations they build.

"state" is the env's flat float32 observation; "pixels" observes {"image": uint8 [H, W, C]} alone;
"pixels+proprio" adds {"proprio": float32 [P]}, the robot's own state (joints, gripper), never the task's
(goal, objects), which the image must show. An env built with `privileged=True` adds to a pixel mode's
observation {"privileged": float32 [S]}, its "state" observation of the same step, which only a learner's critic
or a teacher may read (`actor_observation` removes it).
"""

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.export.numpy_policy import IMAGE, PROPRIO  # declared there: policies run without JAX read them
from jaxarm.ranges import Range, check_value

OBS_MODES = ("state", "pixels", "pixels+proprio")
RESOLUTION = Range(ge=8, le=1 << 10)
"""A camera image's side in pixels: at most 1,024, 16 times the default 64, checked before an env is built (a side
of 1e6 asked XLA for 256 TB at the first reset and ended in its out-of-memory traceback)."""
PRIVILEGED = "privileged"
"""Key of the privileged part in a dict observation: the env's state observation (see the module docstring)."""


def check_obs_mode(obs_mode: str, resolution: int, privileged: bool = False) -> None:
    """ValueError naming the valid choices for an unknown `obs_mode`, a resolution out of `RESOLUTION`, or
    `privileged` with obs_mode "state" (whose observation is the state observation already)."""
    if obs_mode not in OBS_MODES:
        raise ValueError(f"obs_mode must be one of {', '.join(OBS_MODES)}, got {obs_mode!r}")
    check_value("resolution", resolution, int, RESOLUTION)
    if privileged and obs_mode == "state":
        raise ValueError('privileged=True adds the state observation to a pixel obs_mode; "state" observes it alone')


def observation_parts(
    obs_mode: str, image_shape: tuple[int, ...], proprio_size: int, privileged_size: int | None = None
) -> dict[str, jax.ShapeDtypeStruct]:
    """`EnvSpec.observation_parts` of a pixel mode: the uint8 image, the float32 proprio in "pixels+proprio", and
    the float32 [privileged_size] state observation unless `privileged_size` is None."""
    parts = {IMAGE: jax.ShapeDtypeStruct(image_shape, jnp.uint8)}
    if obs_mode == "pixels+proprio":
        parts[PROPRIO] = jax.ShapeDtypeStruct((proprio_size,), jnp.float32)
    if privileged_size is not None:
        parts[PRIVILEGED] = jax.ShapeDtypeStruct((privileged_size,), jnp.float32)
    return parts


def pixel_observation(
    obs_mode: str, image: jax.Array, proprio: jax.Array, privileged: jax.Array | None = None
) -> Mapping[str, jax.Array]:
    """The dict observation of a pixel mode from its image and proprio (dropped in "pixels"), with the state
    observation `privileged` unless None."""
    obs = {IMAGE: image}
    if obs_mode == "pixels+proprio":
        obs[PROPRIO] = proprio
    if privileged is not None:
        obs[PRIVILEGED] = privileged
    return obs


def actor_observation(obs: Any) -> Any:
    """What a policy may read of an observation (batched or not): all of it but the privileged part."""
    if not isinstance(obs, Mapping):
        return obs
    return {name: part for name, part in obs.items() if name != PRIVILEGED}


def with_image(obs: Mapping[str, jax.Array], image: jax.Array) -> dict[str, jax.Array]:
    """A dict observation with its image part replaced by `image`."""
    return {**obs, IMAGE: image}


def with_camera_views(frame: np.ndarray, obs: Any) -> np.ndarray:
    """Outside jit: a rendered frame uint8 [H, W, 3] with what the observation's camera saw to its right, each
    image channel (gray, depth, ...) as a gray tile scaled up to the frame's height; `frame` as it is for a flat
    observation."""
    if not isinstance(obs, Mapping) or IMAGE not in obs:
        return frame
    image = np.asarray(obs[IMAGE])
    height = frame.shape[0]
    scale = max(1, height // image.shape[0])
    tiles = []
    for channel in np.moveaxis(image, -1, 0):
        tile = np.repeat(np.repeat(channel, scale, axis=0), scale, axis=1)[:height]
        tile = np.pad(tile, ((0, height - tile.shape[0]), (0, 0)))
        tiles.append(np.repeat(tile[..., None], 3, axis=-1))
    return np.concatenate([frame, *tiles], axis=1)
