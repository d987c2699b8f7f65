"""The planar N-link reaching arm ("arm2d"), the classic 2-link tutorial arm generalised.

Defaults reproduce the tutorial: a 400x400 world, the base at (200, 200), two links of 100, joint angles
θ ← (θ + clip(a, −1, 1)·0.1) mod 2π, a goal square of side 40, reward −‖goal − finger‖/400 plus 1 while the
finger is strictly inside the goal square, terminated once the goal has been held for more than 50
consecutive steps, truncated at 200 steps. Observation for N links (4N + 1 values): every link end's
position / (world/2), then every (goal − link end) / world, then on_goal. For N = 2 that is the tutorial's
[elbow/200, finger/200, (goal−elbow)/400, (goal−finger)/400, on_goal].
"""

import jax
import jax.numpy as jnp
from flax import struct

from jaxarm.envs.base import Env, EnvSpec, Transition

GOAL_FIXED = 0
"""goal_mode: the goal is `fixed_goal` at every reset."""
GOAL_UNIFORM_WORLD = 1
"""goal_mode: uniform over the whole world square (some goals are unreachable)."""
GOAL_UNIFORM_REACHABLE = 2
"""goal_mode: uniform over the annulus the finger can reach."""


@struct.dataclass
class Arm2dParams:
    """Everything a user may randomise or sweep. Link count is static (the constructor's `num_links`).

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

    link_lengths: jax.Array
    base_pos: jax.Array
    world_size: jax.Array
    goal_size: jax.Array
    goal_mode: jax.Array
    fixed_goal: jax.Array
    action_scale: jax.Array
    distance_weight: jax.Array
    goal_bonus: jax.Array
    success_bonus: jax.Array
    hold_steps: jax.Array
    max_episode_steps: jax.Array


@struct.dataclass
class Arm2dSim:
    """Task state. angles: [N] absolute-increment joint angles in [0, 2π); goal: [2]; hold_count: []."""

    angles: jax.Array
    goal: jax.Array
    hold_count: jax.Array


@struct.dataclass
class Arm2dInfo:
    """Per-step diagnostics: distance [] (normalised by world size), on_goal [] bool, goal_reachable [] bool."""

    distance: jax.Array
    on_goal: jax.Array
    goal_reachable: jax.Array


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


class Arm2d(Env[Arm2dParams, Arm2dSim]):
    """N-link planar reaching arm. Constructor args are static: `num_links` fixes the shapes."""

    def __init__(self, num_links: int = 2):
        if num_links < 1:
            raise ValueError(f"num_links must be >= 1, got {num_links}")
        self.num_links = num_links
        self.spec = EnvSpec(observation_shape=(4 * num_links + 1,), action_shape=(num_links,))

    def default_params(self) -> Arm2dParams:
        f32 = jnp.float32
        return Arm2dParams(
            link_lengths=jnp.full((self.num_links,), 200.0 / self.num_links, f32),
            base_pos=jnp.array([200.0, 200.0], f32),
            world_size=jnp.array(400.0, f32),
            goal_size=jnp.array(40.0, f32),
            goal_mode=jnp.array(GOAL_FIXED, jnp.int32),
            fixed_goal=jnp.array([100.0, 100.0], f32),
            action_scale=jnp.array(0.1, f32),
            distance_weight=jnp.array(1.0, f32),
            goal_bonus=jnp.array(1.0, f32),
            success_bonus=jnp.array(0.0, f32),
            hold_steps=jnp.array(50, jnp.int32),
            max_episode_steps=jnp.array(200, jnp.int32),
        )

    def render(self, state, params: Arm2dParams):
        from jaxarm.envs.arm2d.render import draw_frame

        return draw_frame(state.sim, params)

    def _observe(self, sim: Arm2dSim, params: Arm2dParams) -> jax.Array:
        ends = link_end_positions(sim.angles, params)
        on_goal = (sim.hold_count > 0).astype(jnp.float32)[None]
        return jnp.concatenate(
            [(ends / (params.world_size / 2)).ravel(), ((sim.goal - ends) / params.world_size).ravel(), on_goal]
        )

    def _info(self, sim: Arm2dSim, params: Arm2dParams, on_goal: jax.Array) -> Arm2dInfo:
        finger = link_end_positions(sim.angles, params)[-1]
        return Arm2dInfo(
            distance=jnp.linalg.norm(sim.goal - finger) / params.world_size,
            on_goal=on_goal,
            goal_reachable=goal_reachable(sim.goal, params),
        )

    def _reset(self, key, params):
        # One draw for everything: each threefry call costs more than the arm's maths (see BENCHMARKS.md).
        uniforms = jax.random.uniform(key, (self.num_links + 4,))
        sim = Arm2dSim(
            angles=uniforms[: self.num_links] * 2 * jnp.pi,
            goal=sample_goal(uniforms[self.num_links :], params),
            hold_count=jnp.zeros((), jnp.int32),
        )
        return sim, self._observe(sim, params), self._info(sim, params, jnp.zeros((), jnp.bool_))

    def _transition(self, sim, action, params):
        angles = jnp.mod(sim.angles + action * params.action_scale, 2 * jnp.pi)
        finger = link_end_positions(angles, params)[-1]
        on_goal = jnp.all(jnp.abs(finger - sim.goal) < params.goal_size / 2)
        hold_count = jnp.where(on_goal, sim.hold_count + 1, 0)
        sim = Arm2dSim(angles=angles, goal=sim.goal, hold_count=hold_count)
        info = self._info(sim, params, on_goal)
        terminated = hold_count > params.hold_steps
        return Transition(
            sim=sim,
            obs=self._observe(sim, params),
            reward=(
                -params.distance_weight * info.distance
                + params.goal_bonus * on_goal
                + params.success_bonus * terminated
            ),
            terminated=terminated,
            success=terminated,
            info=info,
        )
