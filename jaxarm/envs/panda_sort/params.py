"""Params of the Panda sorter: everything a user may randomise or sweep, as one pytree of arrays.

vmap over a batch of these is domain randomisation (friction, object masses and sizes apply per env
through the mjx.Model fields the env replaces each step). Counts and modes are constructor arguments.
"""

from typing import ClassVar

import jax
from flax import struct

from jaxarm.envs.panda.params import ArmParams
from jaxarm.ranges import COUNT, NON_NEGATIVE, POSITIVE, UNIT_INTERVAL, ranged


@struct.dataclass
class PandaSortParams(ArmParams):
    """Task, action and randomisation parameters (scalars unless noted).

    Each field declares its default and allowed values (`ranged`, checked by `jaxarm.envs.override_params`); all
    are finite. The robot's own (IK damping and posture gain, start noise, action latency; servo gain, damping,
    friction, force limit and control period scales) are `ArmParams`', documented there.

    The shaping terms pay changes of potentials (see reward.py), so their weights set how strongly each stage
    pulls without creating any reward for lingering; by default one object's stages are worth 1 each.

    Attributes:
      max_episode_steps: time limit (truncation), in env steps of 0.04 s.
      ee_step: tool-centre target displacement per unit action per axis (metres) in `ee` mode, from the
        measured tool centre: the servos cover about a third of it in a step (6.4-6.8 mm for 2 cm). With a
        `running_target` env it moves the target the servos chase, so the tool moves this far per step once
        under way. 2 cm: carried at 2 cm of target per step, with full reversals, every shape and size stayed
        in the grip; at 2.5 cm the largest cube and cylinders slipped out (the servos' accelerations outrun
        the fingers' friction).
      ee_yaw_step: turn of the hand's target about the vertical per unit action (radians) in `ee` mode, as
        `ee_step`. 0.1: the hand turns mostly at joint 7, whose speed limit (2.61 rad/s) allows 0.104 rad per
        step; at the former 0.2 the limited targets turned the hand by half the step.
      joint_step: joint target change per unit action (radians) in `joint` mode, as `ee_step`.
      max_lead: with `running_target`, how far the tool-centre target may lead the measured tool centre per axis
        (metres): three steps of `ee_step` are under way at a steady speed, so it stands above that; a blocked
        tool presses no harder than this lead makes its servos.
      max_yaw_lead: the same for the hand's yaw (radians).
      max_joint_lead: the same for each joint's target in `joint` mode (radians).
      step_reward: reward every step (a time cost).
      floor_reward: reward when an object falls below the table top.
      wrong_bin_reward: reward when an object enters a bin of another shape.
      correct_bin_reward: reward when an object enters the bin of its shape.
      reach_weight: weight of the reach potential 1 − tanh(d / reach_scale), d from the tool centre to an
        object.
      reach_scale: distance over which the reach term rises (metres).
      grasp_weight: weight of the grasp potential, 1 while an object is held between the fingers.
      lift_weight: weight of the lift potential, a held object's lift over its resting height ÷ `lift_height`
        (at most 1).
      carry_weight: weight of the carry potential lift · (1 − tanh(d / carry_scale)), d from a held object to
        the point `carry_height` above the centre of its own bin.
      lift_height: lift at which the lift term saturates (metres).
      carry_scale: distance over which the carry term rises (metres).
      carry_height: height above the table of the carry target (metres): over the bin walls, and in a straight
        line from anywhere in the spawn region without touching them.
      toss_weight: weight of the toss potential 1 − tanh(d / toss_scale), d the horizontal distance from an
        in-play object, held or not, to the centre of its own bin (from where it would land, `toss_flight`; for
        one that fell to the floor, from where it dropped below the table top): it rises while an object flies
        towards its bin, where the carry term (held objects only) cannot follow a throw (the tosser; 0 elsewhere).
      toss_scale: distance over which the toss term rises (metres).
      toss_flight: how far along the path it would fly the toss term places an in-play object: 0 where it is,
        1 where its centre would drop below the floor line (`FLOOR_Z`) if it were let go now, on a ballistic path
        from its position and velocity (an object at rest is where it is either way). At 1 a swing towards the
        bin pays as the object gathers speed, a release keeps what the swing earned, and stopping hands it back.
      held_start_prob: chance that an episode starts with the focus object (a slot drawn uniformly per
        episode) already between the closed fingers, at the arm's start pose (a curriculum: the policy sees
        carrying and releasing before it can grasp; evaluate with 0).
      ready_start_prob: chance that an episode starts grasp-ready: the focus object on the table right under
        the tool, between the open fingers of the lowered arm, or (half of these) below them at a random height
        and yaw (the next stages of that curriculum; evaluate with 0).
      wind_up_start_prob: chance that a held start begins wound up to throw, at rest: the arm at the scripted
        throw's wind-up posture (`curriculum.WIND_UP_POSTURE`) with its base turned to face the held object's own
        bin (the tosser's curriculum: the policy meets the swing and the release before the wind-up; evaluate
        with 0).
      wind_up_spread: how far back towards the held start's posture a wound-up start may begin: the arm starts
        a fraction of the way from that posture to the wind-up drawn uniformly from [1 − spread, 1], in joint
        space (0: always wound up; 1: anywhere on the way, so the policy also meets the wind-up from each point
        of it).
      presorted_prob: chance that each object other than the focus starts already in its own bin, out of play
        (a curriculum over object count: with several objects, episodes with fewer left to sort; it earns no
        placement reward; evaluate with 0).
      object_size: nominal half-size / radius of an object (metres).
      size_scale_low: lower bound of the uniform size factor.
      size_scale_high: upper bound of the uniform size factor.
      density: object density (kg/m³); mass follows the shape's volume.
      mass_scale: factor on every object's mass and inertia.
      object_friction: sliding friction of objects against tables, bins, the blocker and each other.
      finger_friction: sliding friction between the gripper and objects.
      obs_noise: standard deviation of Gaussian noise added to every observation entry each step (in its own
        units: metres, radians, m/s), as a sensor would.
      object_pose_noise: standard deviation of Gaussian noise on each object's observed position (metres), drawn
        every step, as an object detector would; what the observation derives from it (offsets to the tool and the
        bin) follows the noisy position.
      object_pose_bias: standard deviation of a Gaussian error on each object's observed position (metres) drawn
        once per episode and kept, as a pose estimator's calibration would err (`object_pose_noise` is drawn
        afresh every step); the derived offsets follow it too.
    """

    max_episode_steps: jax.Array = ranged(750, COUNT)
    ee_step: jax.Array = ranged(0.02, POSITIVE)
    ee_yaw_step: jax.Array = ranged(0.1, NON_NEGATIVE)
    joint_step: jax.Array = ranged(0.1, POSITIVE)
    max_lead: jax.Array = ranged(0.08, POSITIVE)
    max_yaw_lead: jax.Array = ranged(0.8, POSITIVE)
    max_joint_lead: jax.Array = ranged(0.4, POSITIVE)
    step_reward: jax.Array = ranged(-1.0)
    floor_reward: jax.Array = ranged(-50.0)
    wrong_bin_reward: jax.Array = ranged(200.0)
    correct_bin_reward: jax.Array = ranged(500.0)
    reach_weight: jax.Array = ranged(1.0)
    reach_scale: jax.Array = ranged(0.1, POSITIVE)
    grasp_weight: jax.Array = ranged(1.0)
    lift_weight: jax.Array = ranged(1.0)
    carry_weight: jax.Array = ranged(1.0)
    lift_height: jax.Array = ranged(0.1, POSITIVE)
    carry_scale: jax.Array = ranged(0.2, POSITIVE)
    carry_height: jax.Array = ranged(0.15, NON_NEGATIVE)
    toss_weight: jax.Array = ranged(0.0)
    toss_scale: jax.Array = ranged(0.5, POSITIVE)
    toss_flight: jax.Array = ranged(0.0, UNIT_INTERVAL)
    held_start_prob: jax.Array = ranged(0.0, UNIT_INTERVAL)
    ready_start_prob: jax.Array = ranged(0.0, UNIT_INTERVAL)
    wind_up_start_prob: jax.Array = ranged(0.0, UNIT_INTERVAL)
    wind_up_spread: jax.Array = ranged(0.0, UNIT_INTERVAL)
    presorted_prob: jax.Array = ranged(0.0, UNIT_INTERVAL)
    object_size: jax.Array = ranged(0.025, POSITIVE)
    size_scale_low: jax.Array = ranged(0.5, POSITIVE)
    size_scale_high: jax.Array = ranged(1.5, POSITIVE)
    density: jax.Array = ranged(600.0, POSITIVE)
    mass_scale: jax.Array = ranged(1.0, POSITIVE)
    object_friction: jax.Array = ranged(0.8, NON_NEGATIVE)
    finger_friction: jax.Array = ranged(2.5, NON_NEGATIVE)
    obs_noise: jax.Array = ranged(0.0, NON_NEGATIVE)
    object_pose_noise: jax.Array = ranged(0.0, NON_NEGATIVE)
    object_pose_bias: jax.Array = ranged(0.0, NON_NEGATIVE)

    ORDERED: ClassVar = (("size_scale_low", "size_scale_high"),)
    """(low, high) pairs of fields that must satisfy low <= high."""
