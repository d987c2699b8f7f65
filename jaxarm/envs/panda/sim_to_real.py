"""What separates a simulated Panda from a real one, as functions of env params: servo gains and damping,
action latency and sensor noise. Tasks apply them where they build their model, act and observe, and their
params extend `RobotParams`; nothing here knows about a task.
"""

import jax
import jax.numpy as jnp
from flax import struct
from mujoco import mjx

from jaxarm.envs.panda.robot import PandaIds
from jaxarm.ranges import NON_NEGATIVE, POSITIVE, ranged


@struct.dataclass
class RobotParams:
    """The robot's randomisable params, shared by every Panda task's params (scalars).

    Attributes:
      action_latency: int32, control steps (0.04 s) between a policy's action and the robot acting on it, at
        most the env's `max_action_latency`; meanwhile the commands of earlier steps hold (an episode starts
        with zero actions queued).
      servo_gain_scale: factor on the arm servos' stiffness (kp).
      joint_damping_scale: factor on the arm's damping: the servos' kv and the joints' passive damping.
    """

    action_latency: jax.Array = ranged(NON_NEGATIVE)
    servo_gain_scale: jax.Array = ranged(POSITIVE)
    joint_damping_scale: jax.Array = ranged(NON_NEGATIVE)


def robot_defaults() -> dict[str, jax.Array]:
    """`RobotParams`' defaults, the nominal robot: no latency, the model's own gains and damping."""
    return {
        "action_latency": jnp.array(0, jnp.int32),
        "servo_gain_scale": jnp.array(1.0, jnp.float32),
        "joint_damping_scale": jnp.array(1.0, jnp.float32),
    }


def with_servo_scales(model: mjx.Model, robot: PandaIds, gain_scale: jax.Array, damping_scale: jax.Array) -> mjx.Model:
    """`model` with the arm servos' stiffness kp times `gain_scale` and their kv and the arm joints' passive
    damping times `damping_scale` (a position servo's force is kp · ctrl − kp · q − kv · qdot)."""
    actuators, dofs = robot.arm_actuators, robot.arm_qpos
    gain = model.actuator_gainprm.at[actuators, 0].multiply(gain_scale)
    bias = model.actuator_biasprm.at[actuators, 1].multiply(gain_scale)
    bias = bias.at[actuators, 2].multiply(damping_scale)
    return model.replace(
        actuator_gainprm=gain,
        actuator_biasprm=bias,
        dof_damping=model.dof_damping.at[dofs].multiply(damping_scale),
    )


def delayed_action(queued: jax.Array, action: jax.Array, latency: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(the action the servos receive now [A], the queue after this step [L, A]).

    `queued` [L, A] holds the last L actions, newest first; `action` [A] is this step's. With `latency` k (clipped
    to 0..L) the servos receive the action of k steps ago: `action` itself for k = 0, `queued[k - 1]` otherwise.
    """
    history = jnp.concatenate([action[None], queued])
    applied = history[jnp.clip(latency, 0, queued.shape[0])]
    return applied, history[:-1]


def with_noise(values: jax.Array, key: jax.Array, std: jax.Array) -> jax.Array:
    """`values` plus Gaussian noise of standard deviation `std` (each entry independent; exact for std 0)."""
    return values + std * jax.random.normal(key, values.shape, values.dtype)
