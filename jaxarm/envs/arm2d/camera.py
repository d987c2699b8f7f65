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


def pixel_centres(resolution: int, world_size: jax.Array) -> tuple[jax.Array, jax.Array]:
    """World x [1, R] of every column's pixel centres and y [R, 1] of every row's; row 0 is the top of the world
    (largest y). Together they broadcast to the image's [R, R]."""
    ticks = (jnp.arange(resolution, dtype=jnp.float32) + 0.5) * (world_size / resolution)
    return ticks[None, :], (world_size - ticks)[:, None]


def segment_distance(x: jax.Array, y: jax.Array, start: jax.Array, end: jax.Array) -> jax.Array:
    """Distance from points (x, y) (broadcastable arrays) to the segment from `start` [2] to `end` [2]."""
    dx, dy = end[0] - start[0], end[1] - start[1]
    along = jnp.clip(((x - start[0]) * dx + (y - start[1]) * dy) / jnp.maximum(dx * dx + dy * dy, 1e-12), 0.0, 1.0)
    return jnp.sqrt((x - start[0] - along * dx) ** 2 + (y - start[1] - along * dy) ** 2)


def square_signed_distance(x: jax.Array, y: jax.Array, centre: jax.Array, side: jax.Array) -> jax.Array:
    """Signed distance from points (x, y) (broadcastable arrays) to an axis-aligned square (negative inside)."""
    excess_x, excess_y = jnp.abs(x - centre[0]) - side / 2, jnp.abs(y - centre[1]) - side / 2
    outside = jnp.sqrt(jnp.maximum(excess_x, 0.0) ** 2 + jnp.maximum(excess_y, 0.0) ** 2)
    return outside + jnp.minimum(jnp.maximum(excess_x, excess_y), 0.0)


def coverage(signed_distance: jax.Array, pixel_size: jax.Array) -> jax.Array:
    """Fraction of a pixel a shape covers, from the signed distance at its centre: [...] in [0, 1]."""
    return jnp.clip(0.5 - signed_distance / pixel_size, 0.0, 1.0)


def grayscale_image(sim: Arm2dSim, params: Arm2dParams, resolution: int) -> jax.Array:
    """One state seen from above: uint8 [resolution, resolution, 1]. Written per component, each link in turn,
    so that XLA fuses the whole image into one element-wise loop (as the Panda caster, BENCHMARKS.md)."""
    x, y = pixel_centres(resolution, params.world_size)
    pixel_size = params.world_size / resolution
    joints = jnp.concatenate([params.base_pos[None], link_end_positions(sim.angles, params)])
    link_distance = segment_distance(x, y, joints[0], joints[1])
    for link in range(1, joints.shape[0] - 1):
        link_distance = jnp.minimum(link_distance, segment_distance(x, y, joints[link], joints[link + 1]))
    arm = coverage(link_distance - LINK_RADIUS * params.world_size, pixel_size)
    goal = coverage(square_signed_distance(x, y, sim.goal, params.goal_size), pixel_size)
    brightness = GOAL_LEVEL * goal * (1.0 - arm) + ARM_LEVEL * arm
    return jnp.round(brightness * 255.0).astype(jnp.uint8)[..., None]
