"""A top-down grayscale camera over the arm2d world, rasterised in pure JAX (jit-, vmap- and grad-free-safe).

Each pixel's coverage by a shape is read from the shape's signed distance at the pixel's centre:
clip(0.5 − distance / pixel, 0, 1), a one-pixel linear ramp across every edge (cheap anti-aliasing, so that
a sub-pixel move of the arm still changes the image). The goal square is drawn at `GOAL_LEVEL`, the links
(capsules of radius `LINK_RADIUS` × world size) over it at `ARM_LEVEL`, on a black background. The image's
rows run down the world's y axis, as in `render.draw_frame`.

It must stay free of env logic (rewards, observations): the env decides what to show.
"""

import jax
import jax.numpy as jnp

from jaxarm.envs.arm2d.arm import Arm2dParams, Arm2dSim, link_end_positions

GOAL_LEVEL = 0.4
"""Brightness (0–1) of the goal square."""
ARM_LEVEL = 1.0
"""Brightness (0–1) of the links."""
LINK_RADIUS = 0.025
"""Half the drawn thickness of a link, as a fraction of the world size (10 units in the default 400 world)."""


def pixel_centres(resolution: int, world_size: jax.Array) -> jax.Array:
    """[R, R, 2] world (x, y) of every pixel's centre; row 0 is the top of the world (largest y)."""
    ticks = (jnp.arange(resolution, dtype=jnp.float32) + 0.5) * (world_size / resolution)
    x = jnp.broadcast_to(ticks[None, :], (resolution, resolution))
    y = jnp.broadcast_to(world_size - ticks[:, None], (resolution, resolution))
    return jnp.stack([x, y], axis=-1)


def segment_distance(points: jax.Array, start: jax.Array, end: jax.Array) -> jax.Array:
    """Distance from points [..., 2] to the segment from `start` [2] to `end` [2]: [...]."""
    direction = end - start
    along = jnp.sum((points - start) * direction, axis=-1) / jnp.maximum(jnp.sum(direction**2), 1e-12)
    nearest = start + jnp.clip(along, 0.0, 1.0)[..., None] * direction
    return jnp.linalg.norm(points - nearest, axis=-1)


def square_signed_distance(points: jax.Array, centre: jax.Array, side: jax.Array) -> jax.Array:
    """Signed distance from points [..., 2] to an axis-aligned square (negative inside): [...]."""
    excess = jnp.abs(points - centre) - side / 2
    outside = jnp.linalg.norm(jnp.maximum(excess, 0.0), axis=-1)
    inside = jnp.minimum(jnp.max(excess, axis=-1), 0.0)
    return outside + inside


def coverage(signed_distance: jax.Array, pixel_size: jax.Array) -> jax.Array:
    """Fraction of a pixel a shape covers, from the signed distance at its centre: [...] in [0, 1]."""
    return jnp.clip(0.5 - signed_distance / pixel_size, 0.0, 1.0)


def grayscale_image(sim: Arm2dSim, params: Arm2dParams, resolution: int) -> jax.Array:
    """One state seen from above: uint8 [resolution, resolution, 1]."""
    points = pixel_centres(resolution, params.world_size)
    pixel_size = params.world_size / resolution
    joints = jnp.concatenate([params.base_pos[None], link_end_positions(sim.angles, params)])
    link_distances = jax.vmap(segment_distance, in_axes=(None, 0, 0))(points, joints[:-1], joints[1:])
    arm = coverage(jnp.min(link_distances, axis=0) - LINK_RADIUS * params.world_size, pixel_size)
    goal = coverage(square_signed_distance(points, sim.goal, params.goal_size), pixel_size)
    brightness = GOAL_LEVEL * goal * (1.0 - arm) + ARM_LEVEL * arm
    return jnp.round(brightness * 255.0).astype(jnp.uint8)[..., None]
