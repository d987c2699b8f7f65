"""The sorter's per-env state: the physics that persists between steps and the episode's objects."""

import jax

from jaxarm.envs.panda.base import ArmSim


class PandaSortSim(ArmSim):
    """Physics and task state of one env (N = objects_count): the robot's share (`ArmSim`; its qpos and qvel then
    hold 7 and 6 per object: position and quaternion, linear world and angular local velocity), and the sorter's.

    Attributes:
      shape: [N] int32 SHAPE_* of each object.
      size: [N] half-size / radius of each object (metres).
      colour: [N, 3] RGB of each object; drawn only, never observed, unrelated to the shape.
      outcome: [N] int32 IN_PLAY, IN_CORRECT_BIN, IN_WRONG_BIN or ON_FLOOR (reward.py).
      exit_xy: [N, 2] where each out-of-play object left play, horizontally (metres): for one that fell, where
        it dropped below the table top (zeros while in play and for presorted objects).
      target: [] int32 the slot being worked on: the curricula's object at reset; when it leaves play, the
        in-play object nearest the tool centre. Used only by envs built with `target_first`.
      potential: [S] weighted shaping potentials (`reward.SHAPING_TERMS`) of the current state.
      pose_error: [N, 3] each object's position-estimate error per metre of `object_pose_bias` (standard normal),
        drawn at reset and kept for the episode.
    """

    shape: jax.Array
    size: jax.Array
    colour: jax.Array
    outcome: jax.Array
    exit_xy: jax.Array
    target: jax.Array
    potential: jax.Array
    pose_error: jax.Array
