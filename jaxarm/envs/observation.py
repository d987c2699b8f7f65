"""Observation modes an env with a camera offers, and the dict observations they build.

"state" is the env's flat float32 observation; "pixels" observes {"image": uint8 [H, W, C]} alone;
"pixels+proprio" adds {"proprio": float32 [P]}, the robot's own state (joints, gripper), never the task's
(goal, objects), which the image must show.
"""

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

OBS_MODES = ("state", "pixels", "pixels+proprio")
IMAGE = "image"
"""Key of the camera image in a dict observation."""
PROPRIO = "proprio"
"""Key of the proprioceptive part in a dict observation."""


def check_obs_mode(obs_mode: str, resolution: int) -> None:
    """ValueError naming the valid choices for an unknown `obs_mode` or a resolution below 8 pixels."""
    if obs_mode not in OBS_MODES:
        raise ValueError(f"obs_mode must be one of {', '.join(OBS_MODES)}, got {obs_mode!r}")
    if resolution < 8:
        raise ValueError(f"resolution must be at least 8 pixels, got {resolution}")


def observation_parts(
    obs_mode: str, image_shape: tuple[int, ...], proprio_size: int
) -> dict[str, jax.ShapeDtypeStruct]:
    """`EnvSpec.observation_parts` of a pixel mode: the uint8 image, and the float32 proprio in "pixels+proprio"."""
    parts = {IMAGE: jax.ShapeDtypeStruct(image_shape, jnp.uint8)}
    if obs_mode == "pixels+proprio":
        parts[PROPRIO] = jax.ShapeDtypeStruct((proprio_size,), jnp.float32)
    return parts


def pixel_observation(obs_mode: str, image: jax.Array, proprio: jax.Array) -> Mapping[str, jax.Array]:
    """The dict observation of a pixel mode from its image and proprio (dropped in "pixels")."""
    if obs_mode == "pixels+proprio":
        return {IMAGE: image, PROPRIO: proprio}
    return {IMAGE: image}


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
