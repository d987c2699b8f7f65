"""The sorter's per-env state: the physics that persists between steps and the episode's objects."""

import jax
from flax import struct


class PandaSortSim(struct.PyTreeNode):
    """Physics and task state of one env (N = objects_count; J = the robot's arm joints, `PandaBase.arm_dof`).

    Attributes:
      qpos: [nq] generalized positions (arm J, fingers 2, then 7 per object: position, quaternion).
      qvel: [nv] generalized velocities (arm J, fingers 2, then 6 per object: linear world, angular local).
      qacc_warmstart: [nv] the solver's warm start.
      ctrl: [J + 2] actuator targets (arm joints, then the two fingers).
      target_velocity: [J] the arm's targets' rate of change over the last step (rad/s), which the robot's
        acceleration limits bound the next step's from (`PandaBase.limited_ctrl`).
      shape: [N] int32 SHAPE_* of each object.
      size: [N] half-size / radius of each object (metres).
      colour: [N, 3] RGB of each object; drawn only, never observed, unrelated to the shape.
      outcome: [N] int32 IN_PLAY, IN_CORRECT_BIN, IN_WRONG_BIN or ON_FLOOR (reward.py).
      exit_xy: [N, 2] where each out-of-play object left play, horizontally (metres): for one that fell, where
        it dropped below the table top (zeros while in play and for presorted objects).
      target: [] int32 the slot being worked on: the curricula's object at reset; when it leaves play, the
        in-play object nearest the tool centre. Used only by envs built with `target_first`.
      potential: [S] weighted shaping potentials (`reward.SHAPING_TERMS`) of the current state.
      queued_actions: [L, A] the last L actions, newest first, not yet all applied (L = the env's
        `max_action_latency`; `action_latency` picks which one the servos receive).
      noise_key: PRNG key of the observation noise.
      pose_error: [N, 3] each object's position-estimate error per metre of `object_pose_bias` (standard normal),
        drawn at reset and kept for the episode.
      overflow: [] int32 Warp's overflow bits of every step since the first reset (`PandaSimState.overflow`).
    """

    qpos: jax.Array
    qvel: jax.Array
    qacc_warmstart: jax.Array
    ctrl: jax.Array
    target_velocity: jax.Array
    shape: jax.Array
    size: jax.Array
    colour: jax.Array
    outcome: jax.Array
    exit_xy: jax.Array
    target: jax.Array
    potential: jax.Array
    queued_actions: jax.Array
    noise_key: jax.Array
    pose_error: jax.Array
    overflow: jax.Array
