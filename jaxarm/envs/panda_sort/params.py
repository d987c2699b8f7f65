"""Params of the Panda sorter: everything a user may randomise or sweep, as one pytree of arrays.

vmap over a batch of these is domain randomisation (friction, object masses and sizes apply per env
through the mjx.Model fields the env replaces each step). Counts and modes are constructor arguments.
"""

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class PandaSortParams:
    """Task, action and randomisation parameters (scalars unless noted).

    The shaping weights are kept so that the four positive shaping terms together never exceed the
    per-step time cost (0.25 + 0.25 + 0.5 = 1 by default): holding an object near its bin forever then earns
    no more than finishing, so the +500 of a correct placement stays the thing to aim for.

    Attributes:
      max_episode_steps: time limit (truncation), in env steps of 0.04 s.
      ee_step: end-effector displacement per unit action per axis (metres) in `ee` mode.
      joint_step: joint target change per unit action (radians) in `joint` mode.
      ik_damping: damping λ of the damped-least-squares IK (metres-radians).
      ik_posture_gain: null-space pull of the arm towards its home posture per step (fraction of the error).
      step_reward: reward every step (a time cost).
      floor_reward: reward when an object falls below the table top.
      wrong_bin_reward: reward when an object enters a bin of another shape.
      correct_bin_reward: reward when an object enters the bin of its shape.
      reach_weight: weight of −(distance from the tool centre to the nearest in-play object), per metre.
      grasp_weight: reward per step while an object is held between the fingers.
      lift_weight: reward per step for a held object lifted `lift_height` above its resting height (linear).
      carry_weight: reward per step for a lifted object near its bin, weight · lift · exp(−distance / 0.1 m).
      lift_height: lift at which the lift term saturates (metres).
      object_size: nominal half-size / radius of an object (metres).
      size_scale_low: lower bound of the uniform size factor.
      size_scale_high: upper bound of the uniform size factor.
      density: object density (kg/m³); mass follows the shape's volume.
      mass_scale: factor on every object's mass and inertia.
      object_friction: sliding friction of objects against tables, bins, the blocker and each other.
      finger_friction: sliding friction between the gripper and objects.
      home_noise: half-width of the uniform noise on the arm's initial joint angles (radians).
    """

    max_episode_steps: jax.Array
    ee_step: jax.Array
    joint_step: jax.Array
    ik_damping: jax.Array
    ik_posture_gain: jax.Array
    step_reward: jax.Array
    floor_reward: jax.Array
    wrong_bin_reward: jax.Array
    correct_bin_reward: jax.Array
    reach_weight: jax.Array
    grasp_weight: jax.Array
    lift_weight: jax.Array
    carry_weight: jax.Array
    lift_height: jax.Array
    object_size: jax.Array
    size_scale_low: jax.Array
    size_scale_high: jax.Array
    density: jax.Array
    mass_scale: jax.Array
    object_friction: jax.Array
    finger_friction: jax.Array
    home_noise: jax.Array


def default_params() -> PandaSortParams:
    """The defaults described in the class docstring."""

    def f32(value: float) -> jax.Array:
        return jnp.array(value, jnp.float32)

    return PandaSortParams(
        max_episode_steps=jnp.array(750, jnp.int32),
        ee_step=f32(0.05),
        joint_step=f32(0.1),
        ik_damping=f32(0.05),
        ik_posture_gain=f32(0.05),
        step_reward=f32(-1.0),
        floor_reward=f32(-50.0),
        wrong_bin_reward=f32(200.0),
        correct_bin_reward=f32(500.0),
        reach_weight=f32(1.0),
        grasp_weight=f32(0.25),
        lift_weight=f32(0.25),
        carry_weight=f32(0.5),
        lift_height=f32(0.1),
        object_size=f32(0.025),
        size_scale_low=f32(0.5),
        size_scale_high=f32(1.5),
        density=f32(600.0),
        mass_scale=f32(1.0),
        object_friction=f32(0.8),
        finger_friction=f32(2.5),
        home_noise=f32(0.02),
    )
