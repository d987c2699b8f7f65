"""Params of peg insertion: everything a user may randomise or sweep, as one pytree of arrays.

The hole's clearance reshapes the block's walls per env (mjx.Model fields replaced inside the step), so
vmap over a batch of these params trains across clearances too. Geometry that fixes shapes (peg radius,
hole depth) is static, in model.py.
"""

from typing import ClassVar

import jax
from flax import struct

from jaxarm.envs.panda.params import ArmParams
from jaxarm.ranges import COUNT, NON_NEGATIVE, POSITIVE, UNIT_INTERVAL, ranged

RUNNING_TARGET_MAX_LEAD = 0.03
"""`max_lead` of a `running_target` peg (its presets set it; metres). The lead is what bounds the tool's speed: with
joints damped x3 a held unit action moved the tool 1.2 mm per step at the default 1 cm (3.4 mm at x1, of a 5 mm
`ee_step`), 2.5 mm at 2 cm, 3.8 mm at 3 cm and 4.6 mm, still rising, at 4 cm; at x1 it moves the whole step from
2 cm on. 3 cm: three times the default's pressing force when the peg is blocked."""


@struct.dataclass
class PegInsertParams(ArmParams):
    """Task, action and randomisation parameters (scalars, float32 unless noted).

    Each field declares its default and allowed values (`ranged`, checked by `jaxarm.envs.override_params`); all
    are finite. The robot's own (IK damping and posture gain, start noise, action latency; servo gain, damping,
    friction, force limit and control period scales) are `ArmParams`', documented there.

    Attributes:
      max_episode_steps: time limit (truncation), int32, in env steps of 0.04 s.
      ee_step: tool displacement per unit action per axis (metres per step).
      max_lead: the tool target never leads the measured tool centre by more than this per axis (metres),
        which bounds the force the position servos can press with when the peg is blocked.
      clearance: gap between the peg and each wall of the square hole (metres).
      hole_shift: the hole is moved from its nominal place by U(−hole_shift, hole_shift) in x and in y.
      progress_weight: reward weight of the progress term, (previous − current distance) / initial distance.
      success_bonus: reward per step while the peg tip is within `insert_distance` of the hole bottom.
      insert_distance: the peg counts as inserted within this distance of the hole bottom (metres).
      max_distance: terminated when the peg tip is further than this from the hole bottom (metres).
      friction: sliding friction between the peg and the block.
      obs_noise: standard deviation of Gaussian noise on the observed peg tip position (metres) and velocity
        (m/s), drawn every step, as sensors would give them.
      hole_pose_noise: standard deviation of Gaussian noise on the observed hole position (metres), drawn every
        step, as a detector would give it.
      hole_pose_bias: standard deviation of a Gaussian error on the observed hole position (metres) drawn once per
        episode and kept, as a pose estimator's calibration would err.
      surface_gray_spread: each episode the block and the table take a gray of their own (as the task's tutorial
        drew their colours every episode), each U(−spread, spread) off its modelled gray and within 0-1: what the
        cameras see, nothing else.
    """

    max_episode_steps: jax.Array = ranged(100, COUNT)
    ee_step: jax.Array = ranged(0.005, POSITIVE)
    max_lead: jax.Array = ranged(0.01, POSITIVE)
    clearance: jax.Array = ranged(0.001, POSITIVE)
    hole_shift: jax.Array = ranged(0.1, NON_NEGATIVE)
    progress_weight: jax.Array = ranged(1.0)
    success_bonus: jax.Array = ranged(0.1)
    insert_distance: jax.Array = ranged(0.01, POSITIVE)
    max_distance: jax.Array = ranged(0.8, POSITIVE)
    friction: jax.Array = ranged(0.5, NON_NEGATIVE)
    obs_noise: jax.Array = ranged(0.0, NON_NEGATIVE)
    hole_pose_noise: jax.Array = ranged(0.0, NON_NEGATIVE)
    hole_pose_bias: jax.Array = ranged(0.0, NON_NEGATIVE)
    surface_gray_spread: jax.Array = ranged(0.0, UNIT_INTERVAL)

    ORDERED: ClassVar = (("insert_distance", "max_distance"),)
    """(low, high) pairs of fields that must satisfy low <= high."""
