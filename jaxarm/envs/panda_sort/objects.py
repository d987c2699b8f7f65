"""The sorter's objects: geometry and mass per shape and size, where they spawn, and where they are parked.

Every slot is one body with the same three collision geoms (model.py); a shape is a choice of their sizes.
Pure functions of per-slot arrays and the static ids and layout; scoring is reward.py's.
"""

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.envs.panda_sort.layout import Layout
from jaxarm.envs.panda_sort.model import ModelIds

INNER_SCALE = 0.25
"""Size of an object's geoms that do not belong to its shape, per unit size."""
CYLINDER_BOX_HALF = 0.7
"""Half-width of a cylinder's two collision boxes per unit radius: corners at 0.99 r, just inside the circle."""
GRIP_HALF_WIDTH = np.array([1.0, CYLINDER_BOX_HALF, 1.0], np.float32)
"""Half the finger gap that holds a cube, a cylinder (across the octagon's flats) and a sphere, per unit size."""
PARK_ORIGIN = np.array([3.0, 3.0, 1.0], np.float32)
PARK_SPACING = 1.0
"""Out-of-play object k is held at PARK_ORIGIN + k·PARK_SPACING·x, far from everything and from each other."""


def object_geom_sizes(shape: jax.Array | np.ndarray, size: jax.Array | np.ndarray) -> jax.Array:
    """[N] shapes, [N] sizes -> [N, 3, 3] geom_size rows of each slot's box, box45 and sphere.

    The drawn shape's geoms get full size; the others INNER_SCALE of it, deep inside where even a finger
    pressing into the soft contact cannot reach them.
    """
    s, half = size[:, None], INNER_SCALE * size[:, None]
    a = CYLINDER_BOX_HALF * s
    zero = jnp.zeros_like(s)
    cube = [jnp.concatenate([s, s, s], -1), jnp.concatenate([half] * 3, -1), jnp.concatenate([half, zero, zero], -1)]
    cylinder = [jnp.concatenate([a, a, s], -1)] * 2 + [jnp.concatenate([half, zero, zero], -1)]
    sphere = [jnp.concatenate([half] * 3, -1)] * 2 + [jnp.concatenate([s, zero, zero], -1)]
    by_shape = jnp.stack([jnp.stack(rows, 1) for rows in (cube, cylinder, sphere)])  # [3, N, 3, 3]
    return jnp.take_along_axis(by_shape, shape[None, :, None, None], axis=0)[0]


def object_mass_inertia(shape: jax.Array, size: jax.Array, density: jax.Array) -> tuple[jax.Array, jax.Array]:
    """[N] shapes and sizes -> mass [N] and principal inertia [N, 3] of solid cubes, cylinders, spheres.

    Cube of half-size s; cylinder of radius s and height 2s; sphere of radius s.
    """
    volume = jnp.stack([8.0 * size**3, 2.0 * jnp.pi * size**3, 4.0 / 3.0 * jnp.pi * size**3])
    mass = density * jnp.take_along_axis(volume, shape[None], axis=0)[0]
    ms2 = (mass * size**2)[:, None]
    cube = jnp.full((3,), 2.0 / 3.0)
    cylinder = jnp.array([7.0 / 12.0, 7.0 / 12.0, 0.5])
    sphere = jnp.full((3,), 0.4)
    factors = jnp.stack([cube, cylinder, sphere])[shape]
    return mass, ms2 * factors


def spawn_xy(
    key: jax.Array, count: int, layout: Layout, max_extent: jax.Array, centre_slot: jax.Array | int = -1
) -> jax.Array:
    """[count, 2] object positions in distinct cells of the spawn grid, jittered as far as the cell allows.

    `max_extent` bounds every object's horizontal reach from its centre, so objects never overlap. Object
    `centre_slot` (an int, or -1 for none) gets the grid's middle cell (the spawn region's centre lies in it).
    """
    cell_key, jitter_key = jax.random.split(key)
    nx, ny = layout.spawn_cells
    low, high = jnp.array(layout.spawn_low), jnp.array(layout.spawn_high)
    cell = (high - low) / jnp.array([nx, ny])
    order = jax.random.permutation(cell_key, nx * ny)
    middle = (ny // 2) * nx + nx // 2
    at_middle = jnp.argmax(order == middle)
    slot = jnp.maximum(centre_slot, 0)
    swapped = order.at[at_middle].set(order[slot]).at[slot].set(middle)
    chosen = jnp.where(centre_slot >= 0, swapped, order)[:count]
    centre = low + (jnp.stack([chosen % nx, chosen // nx], -1) + 0.5) * cell
    room = jnp.maximum(cell / 2 - max_extent, 0.0)
    return centre + jax.random.uniform(jitter_key, (count, 2), minval=-room, maxval=room)


def pose_index(ids: ModelIds) -> np.ndarray:
    """[N, 7] qpos addresses of each object's pose (position, then quaternion)."""
    return ids.object_qpos[:, None] + np.arange(7)


def velocity_index(ids: ModelIds) -> np.ndarray:
    """[N, 6] dof addresses of each object's velocity (linear, then angular)."""
    return ids.object_qvel[:, None] + np.arange(6)


def object_positions(ids: ModelIds, qpos: jax.Array) -> jax.Array:
    """[nq] -> [N, 3] object centres."""
    return qpos[pose_index(ids)[:, :3]]


def object_velocities(ids: ModelIds, qvel: jax.Array) -> jax.Array:
    """[nv] -> [N, 3] object centres' velocities (world frame)."""
    return qvel[velocity_index(ids)[:, :3]]


def park(ids: ModelIds, qpos: jax.Array, qvel: jax.Array, out_of_play: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Holds every object where `out_of_play` [N] at its parking pose, at rest: (qpos [nq], qvel [nv])."""
    n = len(ids.object_qpos)
    park_pos = PARK_ORIGIN + PARK_SPACING * np.arange(n)[:, None] * np.array([1.0, 0.0, 0.0], np.float32)
    park_pose = np.concatenate([park_pos, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))], -1).astype(np.float32)
    out = out_of_play[:, None]
    pose_idx, vel_idx = pose_index(ids), velocity_index(ids)
    qpos = qpos.at[pose_idx].set(jnp.where(out, park_pose, qpos[pose_idx]))
    qvel = qvel.at[vel_idx].set(jnp.where(out, 0.0, qvel[vel_idx]))
    return qpos, qvel
