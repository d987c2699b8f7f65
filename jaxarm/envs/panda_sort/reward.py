"""Scoring and shaping of the sorter: which bin an object is in, what each step pays, and what a step reports.

An object whose centre enters a bin (inside its walls, below the rim) is scored: `correct_bin_reward` in the
bin of its shape, `wrong_bin_reward` in another. One that drops below the table top pays `floor_reward`.
Either way it leaves play for the rest of the episode (the env parks it), so it is scored exactly once.

Dense shaping is potential-based: each shaping term pays the change of its potential over the step (reach: the tool
centre near an object; grasp: an object held; lift: a held object lifted; carry: a lifted object near the point
above its own bin; toss: an object, flying or held, horizontally near its own bin, or where it would land if let go
now, `toss_flight` of the way there), summed over objects, with an object in its own bin counting as the maximum of
every term and one elsewhere as zero, except that one which fell to the floor keeps the toss term of where it fell:
a throw that falls short of its bin keeps credit for its range and aim.
Over an episode the shaping sums to the final potential minus the first, so no behaviour (hovering with an
object over its bin, say) can farm it.
"""

import dataclasses

import jax
import jax.numpy as jnp
from flax import struct
from mujoco import mjx

# The outcome codes, the thresholds of falling and holding and the shaping terms' names are declared once, where
# the deployment loop (no JAX) scores a real or simulated robot too.
from jaxarm.deploy.scoring import (
    FLOOR_Z,
    GRAVITY,
    HELD_DISTANCE,
    HELD_MIN_SQUEEZE,
    HELD_MIN_WIDTH,
    IN_CORRECT_BIN,
    IN_PLAY,
    IN_WRONG_BIN,
    ON_FLOOR,
    SHAPING_TERMS,
)
from jaxarm.envs.panda_sort.layout import Layout
from jaxarm.envs.panda_sort.model import ModelIds
from jaxarm.envs.panda_sort.objects import object_positions, object_velocities
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.envs.panda_sort.sim import PandaSortSim


class RewardTerms(struct.PyTreeNode):
    """The reward of one step, term by term (they sum to `EnvState.reward`)."""

    time: jax.Array
    floor: jax.Array
    wrong_bin: jax.Array
    correct_bin: jax.Array
    reach: jax.Array
    grasp: jax.Array
    lift: jax.Array
    carry: jax.Array
    toss: jax.Array

    def total(self) -> jax.Array:
        return sum(jax.tree.leaves(self), jnp.zeros((), jnp.float32))

    def shaping(self) -> jax.Array:
        """[] the shaping terms' sum."""
        return sum((getattr(self, name) for name in SHAPING_TERMS), jnp.zeros((), jnp.float32))

    @classmethod
    def zeros(cls) -> "RewardTerms":
        return cls(*(jnp.zeros((), jnp.float32) for _ in dataclasses.fields(cls)))


class PandaSortInfo(struct.PyTreeNode):
    """Per-step diagnostics: the reward terms and this episode's object counts (int32 scalars)."""

    reward_terms: RewardTerms
    correct_count: jax.Array
    wrong_count: jax.Array
    floor_count: jax.Array
    in_play_count: jax.Array


def bin_membership(position: jax.Array, layout: Layout) -> jax.Array:
    """[N, 3] object positions -> [N, 3] bool: centre inside bin k's walls and below its rim."""
    bins = jnp.array(layout.bin_centers)  # [3, 2]
    inside = jnp.all(jnp.abs(position[:, None, :2] - bins[None]) < layout.bin_half, axis=-1)
    return inside & (position[:, None, 2] < layout.bin_wall_height)


def next_outcome(outcome: jax.Array, shape: jax.Array, position: jax.Array, layout: Layout) -> jax.Array:
    """Scores in-play objects at their new [N, 3] positions; out-of-play outcomes never change."""
    in_bin = bin_membership(position, layout)
    in_own_bin = jnp.take_along_axis(in_bin, shape[:, None], axis=1)[:, 0]
    scored = jnp.select(
        [in_own_bin, jnp.any(in_bin, axis=1), position[:, 2] < FLOOR_Z],
        [IN_CORRECT_BIN, IN_WRONG_BIN, ON_FLOOR],
        IN_PLAY,
    )
    return jnp.where(outcome == IN_PLAY, scored, outcome)


def carry_targets(layout: Layout, shape: jax.Array, carry_height: jax.Array) -> jax.Array:
    """[N] shapes -> [N, 3] the point `carry_height` above the centre of each object's own bin."""
    own_bin = jnp.array(layout.bin_centers)[shape]
    return jnp.concatenate([own_bin, jnp.broadcast_to(carry_height, (len(shape), 1))], -1)


def tcp_distances(ids: ModelIds, data: mjx.Data, sim: PandaSortSim) -> jax.Array:
    """[N] distance of each object's centre from the tool centre."""
    return jnp.linalg.norm(object_positions(ids, sim.qpos) - data.site_xpos[ids.robot.tcp_site], axis=-1)


def next_target(ids: ModelIds, data: mjx.Data, sim: PandaSortSim) -> jax.Array:
    """[] int32 the target slot after a step: kept while in play, else the in-play object nearest the tool."""
    in_play = sim.outcome == IN_PLAY
    nearest = jnp.argmin(jnp.where(in_play, tcp_distances(ids, data, sim), jnp.inf))
    return jnp.where(in_play[sim.target], sim.target, nearest).astype(jnp.int32)


def landing_xy(position: jax.Array, velocity: jax.Array, flight: jax.Array) -> jax.Array:
    """[N, 2] where each object's centre would drop below the floor line (`FLOOR_Z`) if let go now, `flight` of
    the way along its ballistic path from `position` [N, 3] with `velocity` [N, 3]: at 0 where it is."""
    rise = velocity[:, 2]
    fall_time = (rise + jnp.sqrt(jnp.maximum(rise**2 + 2 * GRAVITY * (position[:, 2] - FLOOR_Z), 0.0))) / GRAVITY
    return position[:, :2] + flight * jnp.maximum(fall_time, 0.0)[:, None] * velocity[:, :2]


def shaping_potential(
    ids: ModelIds, layout: Layout, data: mjx.Data, sim: PandaSortSim, params: PandaSortParams, target_first: bool
) -> jax.Array:
    """[S] weighted potentials (`SHAPING_TERMS`), each summed over objects (see the module docstring); with
    `target_first`, in-play objects other than the target count zero."""
    in_play = sim.outcome == IN_PLAY
    position = object_positions(ids, sim.qpos)
    distance = tcp_distances(ids, data, sim)
    fingers = sim.qpos[ids.robot.finger_qpos]
    squeeze = jnp.mean(fingers - sim.ctrl[7:])
    held = (
        (distance < sim.size + HELD_DISTANCE)
        & (squeeze > HELD_MIN_SQUEEZE)
        & (jnp.sum(fingers) > HELD_MIN_WIDTH * sim.size)
    )
    lift = held * jnp.clip((position[:, 2] - sim.size) / params.lift_height, 0.0, 1.0)
    carry_target = carry_targets(layout, sim.shape, params.carry_height)
    to_target = jnp.linalg.norm(position - carry_target, axis=-1)
    # The toss term follows an object to where it fell, so one that fell short keeps credit for its range and aim.
    on_floor = sim.outcome == ON_FLOOR
    in_flight = landing_xy(position, object_velocities(ids, sim.qvel), params.toss_flight)
    toss_xy = jnp.where(on_floor[:, None], sim.exit_xy, in_flight)
    toss = 1.0 - jnp.tanh(jnp.linalg.norm(toss_xy - carry_target[:, :2], axis=-1) / params.toss_scale)
    stages = jnp.stack(
        [
            1.0 - jnp.tanh(distance / params.reach_scale),
            held.astype(jnp.float32),
            lift,
            lift * (1.0 - jnp.tanh(to_target / params.carry_scale)),
            toss,
        ]
    )  # [S, N]
    in_own_bin = (sim.outcome == IN_CORRECT_BIN).astype(jnp.float32)
    out_of_play = jnp.stack([in_own_bin + on_floor * toss if name == "toss" else in_own_bin for name in SHAPING_TERMS])
    slots = jnp.arange(len(ids.object_qpos))
    shaped = in_play & (slots == sim.target) if target_first else in_play
    per_object = jnp.where(shaped, stages, out_of_play)
    weights = jnp.stack([getattr(params, f"{name}_weight") for name in SHAPING_TERMS])
    return weights * jnp.sum(per_object, axis=1)


def reward_terms(sim: PandaSortSim, previous: PandaSortSim, params: PandaSortParams) -> RewardTerms:
    """Sparse terms for objects scored this step; shaping as the change of each potential."""
    newly = (previous.outcome == IN_PLAY) & (sim.outcome != IN_PLAY)

    def count(outcome: int) -> jax.Array:
        return jnp.sum(newly & (sim.outcome == outcome)).astype(jnp.float32)

    shaping = dict(zip(SHAPING_TERMS, sim.potential - previous.potential, strict=True))
    return RewardTerms(
        time=params.step_reward,
        floor=params.floor_reward * count(ON_FLOOR),
        wrong_bin=params.wrong_bin_reward * count(IN_WRONG_BIN),
        correct_bin=params.correct_bin_reward * count(IN_CORRECT_BIN),
        **shaping,
    )


def step_info(terms: RewardTerms, outcome: jax.Array) -> PandaSortInfo:
    """The step's diagnostics: its reward terms and how many objects [N] `outcome`s hold each outcome."""

    def count(value: int) -> jax.Array:
        return jnp.sum(outcome == value).astype(jnp.int32)

    return PandaSortInfo(
        reward_terms=terms,
        correct_count=count(IN_CORRECT_BIN),
        wrong_count=count(IN_WRONG_BIN),
        floor_count=count(ON_FLOOR),
        in_play_count=count(IN_PLAY),
    )
