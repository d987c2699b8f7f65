"""The sorter's pure pieces on hand-worked cases, eagerly, without compiling MJX: solid-body masses and inertias,
the per-shape collision geoms, scoring by bin, spawning in distinct cells and the curricula's draws."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.envs.panda_sort import (
    IN_CORRECT_BIN,
    IN_PLAY,
    IN_WRONG_BIN,
    ON_FLOOR,
    SHAPE_CUBE,
    SHAPE_CYLINDER,
    SHAPE_SPHERE,
    make_layout,
)
from jaxarm.envs.panda_sort.curriculum import draw_start
from jaxarm.envs.panda_sort.objects import INNER_SCALE, object_geom_sizes, object_mass_inertia, spawn_xy
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.envs.panda_sort.reward import next_outcome

SHAPES = jnp.array([SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE], jnp.int32)


def test_masses_and_inertias_of_solid_shapes_by_hand():
    size, density = 0.02, 1000.0
    mass, inertia = object_mass_inertia(SHAPES, jnp.full(3, size), jnp.float32(density))
    cube = density * (2 * size) ** 3
    cylinder = density * np.pi * size**2 * (2 * size)
    sphere = density * 4 / 3 * np.pi * size**3
    np.testing.assert_allclose(mass, [cube, cylinder, sphere], rtol=1e-6)
    # Cube of side 2s: m(2s)²/6 about every axis; cylinder of radius s, height 2s: m(3s² + (2s)²)/12 across,
    # ms²/2 along; sphere: 2ms²/5.
    expected = [
        [cube * (2 * size) ** 2 / 6] * 3,
        [cylinder * (3 * size**2 + (2 * size) ** 2) / 12] * 2 + [cylinder * size**2 / 2],
        [2 * sphere * size**2 / 5] * 3,
    ]
    np.testing.assert_allclose(inertia, expected, rtol=1e-5)


def test_only_the_drawn_shape_gets_full_size_geoms():
    size = 0.03
    sizes = np.asarray(object_geom_sizes(SHAPES, jnp.full(3, size)))  # [3 slots, 3 geoms (box, box45, sphere), 3]
    inner = INNER_SCALE * size
    np.testing.assert_allclose(sizes[0, 0], [size] * 3)  # the cube's box
    assert np.all(sizes[0, 1:] <= inner + 1e-9)
    assert np.all(sizes[1, :2, 2] == np.float32(size)) and np.all(sizes[1, 2] <= inner + 1e-9)  # the octagon
    np.testing.assert_allclose(sizes[2, 2, 0], size)  # the sphere
    assert np.all(sizes[2, :2] <= inner + 1e-9)


def test_objects_are_scored_once_by_the_bin_they_fall_in():
    layout = make_layout()
    (cube_x, cube_y), (cylinder_x, cylinder_y) = layout.bin_centers[0], layout.bin_centers[1]
    position = jnp.array(
        [
            [cube_x, cube_y, 0.03],  # a cube in its own bin
            [cube_x, cube_y, 0.03],  # a cylinder in the cube's bin
            [cylinder_x, cylinder_y, layout.bin_wall_height + 0.01],  # above the rim: not in yet
            [0.5, 0.0, -0.2],  # below the table top
            [cube_x, cube_y, 0.03],  # already out of play: never scored again
        ]
    )
    shape = jnp.array([SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_CYLINDER, SHAPE_SPHERE, SHAPE_SPHERE], jnp.int32)
    outcome = jnp.array([IN_PLAY] * 4 + [ON_FLOOR], jnp.int32)
    scored = next_outcome(outcome, shape, position, layout)
    np.testing.assert_array_equal(scored, [IN_CORRECT_BIN, IN_WRONG_BIN, IN_PLAY, ON_FLOOR, ON_FLOOR])


def test_spawned_objects_stand_apart_inside_the_spawn_region():
    layout = make_layout()
    extent = 0.03  # reach of each object from its centre; the cells are 14 cm wide
    xy = np.asarray(spawn_xy(jax.random.key(3), 5, layout, jnp.float32(extent)))
    assert np.all(xy >= np.array(layout.spawn_low)) and np.all(xy <= np.array(layout.spawn_high))
    gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(5) * 1e3
    assert gaps.min() >= 2 * extent - 1e-6


def test_curricula_draw_in_their_proportions():
    params = PandaSortParams().replace(
        held_start_prob=jnp.float32(0.25), ready_start_prob=jnp.float32(0.5), presorted_prob=jnp.float32(1.0)
    )
    keys = jax.random.split(jax.random.key(0), (2, 4000))
    draws = jax.vmap(lambda start, objects: draw_start(start, objects, 3, params))(keys[0], keys[1])
    assert abs(float(draws.held.mean()) - 0.25) < 0.03 and abs(float(draws.ready.mean()) - 0.5) < 0.03
    assert not np.any(draws.held & draws.ready)
    presorted = np.asarray(draws.presorted)
    focus = np.asarray(draws.focus)
    assert not np.any(presorted[np.arange(4000), focus]), "the curricula's object is never presorted"
    assert np.all(presorted.sum(axis=1) == 2), "with probability 1 every other object starts sorted"
    np.testing.assert_array_equal(np.asarray(draws.blend)[np.asarray(draws.held)], 1.0)


def test_wound_up_starts_are_held_starts_and_leave_the_other_draws_as_they_were():
    params = PandaSortParams().replace(held_start_prob=jnp.float32(0.25), ready_start_prob=jnp.float32(0.5))
    keys = jax.random.split(jax.random.key(0), (2, 4000))

    def draws(wind_up_start_prob: float, wind_up_spread: float = 0.0):
        wound = params.replace(
            wind_up_start_prob=jnp.float32(wind_up_start_prob), wind_up_spread=jnp.float32(wind_up_spread)
        )
        return jax.vmap(lambda start, objects: draw_start(start, objects, 3, wound))(keys[0], keys[1])

    plain, wound, spread = draws(0.0), draws(0.5), draws(0.5, 0.5)
    assert not np.any(plain.wound_up)
    held = np.asarray(wound.held)
    assert not np.any(np.asarray(wound.wound_up) & ~held)
    assert abs(float(np.asarray(wound.wound_up)[held].mean()) - 0.5) < 0.05
    np.testing.assert_array_equal(wound.wind_up, 1.0)
    # Spread over [0.5, 1] of the way to the wind-up, uniformly.
    way = np.asarray(spread.wind_up)
    assert 0.5 <= way.min() < 0.51 and 0.99 < way.max() <= 1.0 and abs(way.mean() - 0.75) < 0.01
    np.testing.assert_array_equal(spread.wound_up, wound.wound_up)
    for field in ("focus", "presorted", "held", "ready", "hover", "blend"):
        np.testing.assert_array_equal(getattr(wound, field), getattr(plain, field), err_msg=field)
