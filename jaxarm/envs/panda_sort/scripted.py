"""A hand-written pick-and-place for the sorter in `ee` mode: a baseline, a physics check, a demonstration.

It reads only the observation (object 0's position and relative yaw, the tool centre) and steers the tool
centre towards one target per phase with a capped proportional step, turning the hand to meet the object's
faces on the way down: above the object, down until the pads are level with its centre, close, lift, over
the bin, open. A phase ends when its target is reached (or, when closing, after a few steps). Pure JAX:
`scripted_action` jits, scans and vmaps.
"""

import jax
import jax.numpy as jnp
from flax import struct

from jaxarm.envs.base import EnvState
from jaxarm.envs.panda_sort.env import OBJECT_OBS_SIZE, OBJECT_RELATIVE_YAW, PandaSort
from jaxarm.envs.panda_sort.params import PandaSortParams

PHASE_NAMES = ("above", "down", "close", "lift", "to bin", "open")
OPEN, CLOSED = 1.0, -1.0
PHASE_GRIP = (OPEN, OPEN, CLOSED, CLOSED, CLOSED, OPEN)
MOVING_PHASES = (True, True, False, True, True, False)
"""Phases that end when their target is reached."""
ABOVE = 0.1
"""Height above the object to approach from (metres)."""
CARRY_Z = 0.18
"""Tool-centre height while carrying (metres): the bottom of the largest object clears the bin walls."""
REACHED = 0.01
"""A target is reached within this distance (metres)."""
CLOSE_STEPS = 8
"""Steps the fingers are given to close."""
CARRY_SPEED = 0.6
"""Default cap on each axis of the action (0..1). Since the wrist's servos follow their targets (kp 300, kv 30) and
every target is held within Franka's limits, a 2.5 cm sphere carried at 0.8 slipped out of the grip where the path
turns over the bins; at 0.6 the sphere, cube and cylinder of tests/envs/test_panda_sort.py are all placed, in
212-217 steps (MJX-JAX, the nominal arm, 2026-11-26)."""


@struct.dataclass
class ScriptState:
    """The script's memory: phase [] int32, tool centre where the object was reached [3], closing steps [] int32."""

    phase: jax.Array
    hold: jax.Array
    closing: jax.Array


def tcp_of(env: PandaSort, obs: jax.Array) -> jax.Array:
    """[O] observation -> [3] tool-centre position."""
    start = OBJECT_OBS_SIZE * env.objects_count
    return obs[start : start + 3]


def script_start(env: PandaSort, state: EnvState) -> ScriptState:
    return ScriptState(phase=jnp.int32(0), hold=tcp_of(env, state.obs), closing=jnp.int32(0))


def scripted_action(
    env: PandaSort,
    obs: jax.Array,
    script: ScriptState,
    params: PandaSortParams,
    bin_xy: jax.Array,
    speed: float = CARRY_SPEED,
) -> tuple[jax.Array, ScriptState]:
    """One step of the script for object 0: ([5] action, next script state). `speed` caps each axis (0..1)."""
    phase = script.phase
    obj, tcp = obs[0:3], tcp_of(env, obs)
    over_bin = jnp.append(bin_xy, CARRY_Z)
    grasp = obj - jnp.array([0.0, 0.0, env.robot.pad_above_tcp])
    targets = jnp.stack([obj.at[2].add(ABOVE), grasp, script.hold, script.hold.at[2].set(CARRY_Z), over_bin, over_bin])
    error = targets[phase] - tcp
    # The hand turns by the object's yaw relative to it, folded into (−45°, 45°], before it closes.
    cos4, sin4 = obs[OBJECT_RELATIVE_YAW]
    turn = jnp.where(phase < 2, jnp.arctan2(sin4, cos4) / 4.0, 0.0)
    move = jnp.clip(error / params.ee_step, -speed, speed)
    action = jnp.concatenate(
        [move, jnp.clip(turn / params.ee_yaw_step, -1.0, 1.0)[None], jnp.asarray(PHASE_GRIP)[phase][None]]
    )
    reached = jnp.asarray(MOVING_PHASES)[phase] & (jnp.linalg.norm(error) < REACHED) & (jnp.abs(turn) < 0.05)
    closing = script.closing + (phase == 2)
    next_phase = jnp.minimum(phase + (reached | ((phase == 2) & (closing > CLOSE_STEPS))), len(PHASE_NAMES) - 1)
    return action, ScriptState(phase=next_phase, hold=jnp.where(reached, tcp, script.hold), closing=closing)
