"""Image augmentation for learners that see: DrQ's random shift (Kostrikov et al. 2020).

Each image is padded by repeating its border `pad` pixels and cropped back to its size at a random offset, so a
critic sees every stored frame shifted by up to ±`pad` pixels; frames stay uint8.
"""

from collections.abc import Mapping

import jax
import jax.numpy as jnp

from jaxarm.envs.observation import IMAGE


def random_shift(key: jax.Array, images: jax.Array, pad: int) -> jax.Array:
    """images [B, H, W, C] -> [B, H, W, C], each shifted by its own random offset in [−pad, pad]² pixels."""
    batch, height, width, channels = images.shape
    padded = jnp.pad(images, ((0, 0), (pad, pad), (pad, pad), (0, 0)), mode="edge")
    offsets = jax.random.randint(key, (batch, 2), 0, 2 * pad + 1)

    def crop(image, offset):
        return jax.lax.dynamic_slice(image, (offset[0], offset[1], 0), (height, width, channels))

    return jax.vmap(crop)(padded, offsets)


def shift_observation(key: jax.Array, obs: Mapping[str, jax.Array], pad: int) -> dict[str, jax.Array]:
    """A camera observation [B, ...] with its image randomly shifted (`random_shift`), the rest unchanged."""
    return {**obs, IMAGE: random_shift(key, obs[IMAGE], pad)}
