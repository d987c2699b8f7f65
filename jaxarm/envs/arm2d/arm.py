"""The arm2d arm itself: its params, its state and its geometry (link ends, reach, goals). No env logic, so
that the env and its renderer both build on it.
"""

import jax
import jax.numpy as jnp
from flax import struct

from jaxarm.ranges import COUNT, NON_NEGATIVE, POSITIVE, Range, ranged

GOAL_FIXED = 0
"""goal_mode: the goal is `fixed_goal` at every reset."""
GOAL_UNIFORM_WORLD = 1
"""goal_mode: uniform over the whole world square (some goals are unreachable)."""
GOAL_UNIFORM_REACHABLE = 2
"""goal_mode: uniform over the annulus the finger can reach."""


@struct.dataclass
class Arm2dParams:
    """Everything a user may randomise or sweep. Link count is static (the constructor's `num_links`).

    Each field declares its default and allowed values (`ranged`, checked by `jaxarm.envs.override_params`); all
    are finite. `link_lengths` has no default: the env's `num_links` shapes it.

    Attributes:
      link_lengths: [N] link lengths, world units.
      base_pos: [2] base position.
      world_size: side of the square world; observations are normalised by it.
      goal_size: side of the goal square.
      goal_mode: GOAL_FIXED, GOAL_UNIFORM_WORLD or GOAL_UNIFORM_REACHABLE (int32).
      fixed_goal: [2] goal centre used when goal_mode is GOAL_FIXED.
      action_scale: joint-angle change (radians) per unit action.
      distance_weight: weight of the −distance/world reward term.
      goal_bonus: reward per step with the finger inside the goal square.
      success_bonus: reward on the step that completes the hold (0 in the tutorial). Without it, leaving the
        goal for a step to restart the hold count earns more per-step bonus than finishing the task.
      hold_steps: terminated once the goal has been held for more than this many consecutive steps.
      max_episode_steps: time limit (truncation).
    """

    link_lengths: jax.Array = ranged(allowed=POSITIVE)
    base_pos: jax.Array = ranged([200.0, 200.0])
    world_size: jax.Array = ranged(400.0, POSITIVE)
    goal_size: jax.Array = ranged(40.0, POSITIVE)
    goal_mode: jax.Array = ranged(GOAL_FIXED, Range(choices=(GOAL_FIXED, GOAL_UNIFORM_WORLD, GOAL_UNIFORM_REACHABLE)))
    fixed_goal: jax.Array = ranged([100.0, 100.0])
    action_scale: jax.Array = ranged(0.1, POSITIVE)
    distance_weight: jax.Array = ranged(1.0)
    goal_bonus: jax.Array = ranged(1.0)
    success_bonus: jax.Array = ranged(0.0)
    hold_steps: jax.Array = ranged(50, NON_NEGATIVE)
    max_episode_steps: jax.Array = ranged(200, COUNT)


@struct.dataclass
class Arm2dSim:
    """Task state. angles: [N] absolute-increment joint angles in [0, 2π); goal: [2]; hold_count: []."""

    angles: jax.Array
    goal: jax.Array
    hold_count: jax.Array


def link_end_positions(angles: jax.Array, params: Arm2dParams) -> jax.Array:
    """[N] joint angles -> [N, 2] positions of each link's end (the last row is the finger)."""
    absolute = jnp.cumsum(angles)
    steps = params.link_lengths[:, None] * jnp.stack([jnp.cos(absolute), jnp.sin(absolute)], axis=-1)
    return params.base_pos + jnp.cumsum(steps, axis=0)


def reach_radii(params: Arm2dParams) -> tuple[jax.Array, jax.Array]:
    """Inner and outer radius of the annulus the finger can reach around the base."""
    outer = jnp.sum(params.link_lengths)
    inner = jnp.maximum(0.0, 2.0 * jnp.max(params.link_lengths) - outer)
    return inner, outer


def goal_reachable(goal: jax.Array, params: Arm2dParams) -> jax.Array:
    """Whether some finger position lies strictly inside the goal square: the square meets the annulus."""
    inner, outer = reach_radii(params)
    half = params.goal_size / 2
    nearest = jnp.linalg.norm(jnp.clip(params.base_pos, goal - half, goal + half) - params.base_pos)
    farthest = jnp.linalg.norm(jnp.abs(goal - params.base_pos) + half)
    return (nearest < outer) & (farthest > inner)


def sample_goal(uniforms: jax.Array, params: Arm2dParams) -> jax.Array:
    """[2] goal centre for a new episode from 4 uniform [0, 1) numbers, according to `params.goal_mode`."""
    in_world = uniforms[:2] * params.world_size
    inner, outer = reach_radii(params)
    # Uniform over the annulus's area: the squared radius is uniform.
    radius = jnp.sqrt(inner**2 + uniforms[2] * (outer**2 - inner**2))
    angle = uniforms[3] * 2 * jnp.pi
    in_reach = params.base_pos + radius * jnp.stack([jnp.cos(angle), jnp.sin(angle)])
    return jnp.select(
        [params.goal_mode == GOAL_FIXED, params.goal_mode == GOAL_UNIFORM_WORLD],
        [params.fixed_goal, in_world],
        in_reach,
    ).astype(jnp.float32)
