"""Observation modes an env with a camera offers, and the dict observations they build.

"state" is the env's flat float32 observation; "pixels" observes {"image": uint8 [H, W, C]} alone;
"pixels+proprio" adds {"proprio": float32 [P]}, the robot's own state (joints, gripper), never the task's
(goal, objects), which the image must show.
"""

from collections.abc import Mapping

import jax
import jax.numpy as jnp

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
