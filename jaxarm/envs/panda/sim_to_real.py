"""What separates a simulated Panda from a real one, as functions of env params: servo gains and damping, joint
friction, force limits, the control period, the fingers' pads, action latency, sensor noise, and the cameras' pose,
gray level, depth and view of the fingers. Tasks apply them where they build their model, act and observe, and
their params extend `RobotParams`; nothing here knows about a task.
"""

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from mujoco import mjx

from jaxarm.envs.panda.camera import PoseOffset
from jaxarm.envs.panda.mjx_impl import with_geom_sizes
from jaxarm.envs.panda.robot import RobotIds
from jaxarm.ranges import NON_NEGATIVE, POSITIVE, Range, ranged

CONTROL_PERIOD_SCALES = Range(ge=0.5, le=1.5)
"""Allowed `control_period_scale`s. Past 1.5 (substeps of 15 ms where the scene has 10 ms) the clamped servos
chatter harder: stepping a 0.3 rad target change and back on the sorter's arm in MuJoCo C, the fastest joint
speed was 4.5, 5.1, 5.2, 8.4 and 14 rad/s at 1, 1.25, 1.5, 2 and 3 times the timestep."""
CAMERA_TURNS = Range(ge=-np.pi, le=np.pi)
"""Allowed camera pitch, yaw and roll (radians): past half a turn a rotation is the shorter one the other way."""


@struct.dataclass
class RobotParams:
    """The robot's randomisable params, shared by every Panda task's params (scalars). Their defaults are the
    nominal robot: no latency, the model's own gains, damping, friction, force limits and timestep, the cameras as
    simulated.

    Attributes:
      action_latency: int32, control steps (0.04 s) between a policy's action and the robot acting on it, at
        most the env's `max_action_latency`; meanwhile the commands of earlier steps hold (an episode starts
        with zero actions queued).
      servo_gain_scale: factor on the arm servos' stiffness (kp).
      joint_damping_scale: factor on the arm's damping: the servos' kv and the joints' passive damping.
      joint_friction_scale: factor on the arm joints' Coulomb friction (frictionloss). The nominal arm has none
        (only `dynamics="identified"` does), and MJX fixes which joints have friction rows when the model is put on
        the device, so on the nominal arm this changes nothing.
      force_limit_scale: factor on the arm servos' force limits (forcerange: 87 N·m on joints 1-4, 12 on 5-7).
      control_period_scale: factor on the physics timestep, so each env step spans `CONTROL_DT` times this of
        simulated time (the substeps per step are fixed when the program is traced; see `CONTROL_PERIOD_SCALES`
        for the range): a control loop that runs slower or faster than its nominal rate.
      finger_pad_scale: factor on the size of the fingers' geoms (the pads objects touch) about each one's centre,
        in the physics and so in the cameras: fingertips smaller or larger than the model's, as another model's or
        the real robot's are (menagerie's Panda's pads are 0.71 of jaxarm's across and sit further out).
      camera_shift_x, camera_shift_y, camera_shift_z: metres every camera is moved from its MJCF pose along its
        own x (right), y (up in the image) and z (backwards, away from what it sees) axes: a camera mounted or
        calibrated off its nominal pose (pixel modes only; each camera by the same offset in its own frame).
      camera_pitch, camera_yaw, camera_roll: radians every camera is turned, at its shifted position, about its
        own x, y and z axes (one rotation vector, right-hand rule: +pitch looks up, +yaw left, +roll turns the
        image clockwise), as the shift (`camera.PoseOffset`).
      camera_gray_gain: factor on every camera's gray image, clipped to white: lighting and exposure other than
        the simulated ones (pixel modes only).
      camera_gray_offset: added to every camera's gray (0-1) after the gain, clipped to black and white: ambient
        light or a sensor's black level (pixel modes only).
      camera_depth_offset: metres added to every camera's depth, clipped to its range: a depth camera's
        calibration error (pixel modes only).
      camera_depth_noise: standard deviation (metres) of Gaussian noise on every depth pixel, drawn afresh at
        each step from the task's observation noise key (pixel modes only).
      camera_finger_scale: factor on the size of the fingers' geoms as the cameras draw them, about each one's
        centre (0 hides them), their physics untouched: fingers that look otherwise than the model's pads, as
        another model's or the real robot's do (pixel modes only).
    """

    action_latency: jax.Array = ranged(0, NON_NEGATIVE)
    servo_gain_scale: jax.Array = ranged(1.0, POSITIVE)
    joint_damping_scale: jax.Array = ranged(1.0, NON_NEGATIVE)
    joint_friction_scale: jax.Array = ranged(1.0, NON_NEGATIVE)
    force_limit_scale: jax.Array = ranged(1.0, POSITIVE)
    control_period_scale: jax.Array = ranged(1.0, CONTROL_PERIOD_SCALES)
    finger_pad_scale: jax.Array = ranged(1.0, POSITIVE)
    camera_shift_x: jax.Array = ranged(0.0)
    camera_shift_y: jax.Array = ranged(0.0)
    camera_shift_z: jax.Array = ranged(0.0)
    camera_pitch: jax.Array = ranged(0.0, CAMERA_TURNS)
    camera_yaw: jax.Array = ranged(0.0, CAMERA_TURNS)
    camera_roll: jax.Array = ranged(0.0, CAMERA_TURNS)
    camera_gray_gain: jax.Array = ranged(1.0, NON_NEGATIVE)
    camera_gray_offset: jax.Array = ranged(0.0)
    camera_depth_offset: jax.Array = ranged(0.0)
    camera_depth_noise: jax.Array = ranged(0.0, NON_NEGATIVE)
    camera_finger_scale: jax.Array = ranged(1.0, NON_NEGATIVE)

    @property
    def camera_offset(self) -> PoseOffset:
        """The cameras' pose offset from the shifts [3] and turns [3] above, each camera's in its own frame."""
        return PoseOffset(
            shift=jnp.stack([self.camera_shift_x, self.camera_shift_y, self.camera_shift_z]),
            turn=jnp.stack([self.camera_pitch, self.camera_yaw, self.camera_roll]),
        )


def with_robot_params(model: mjx.Model, robot: RobotIds, params: RobotParams) -> mjx.Model:
    """`model` with `params`' robot randomisation applied: servo gains and damping (`with_servo_scales`), the
    arm joints' friction loss and servo force limits scaled, the fingers' pads resized by `finger_pad_scale`, and
    the timestep scaled by `control_period_scale`. Each is a model field replaced per env, as MJX-JAX and Warp
    both batch them."""
    model = with_servo_scales(model, robot, params.servo_gain_scale, params.joint_damping_scale)
    pads = robot.finger_geoms
    pad_size = model.geom_size[pads] * params.finger_pad_scale
    model = with_geom_sizes(model, pads, pad_size, model.geom_rbound[pads] * params.finger_pad_scale)
    forcerange = model.actuator_forcerange.at[robot.arm_actuators].multiply(params.force_limit_scale)
    return model.replace(
        dof_frictionloss=model.dof_frictionloss.at[robot.arm_qpos].multiply(params.joint_friction_scale),
        actuator_forcerange=forcerange,
        opt=model.opt.replace(timestep=model.opt.timestep * params.control_period_scale),
    )


def with_servo_scales(model: mjx.Model, robot: RobotIds, gain_scale: jax.Array, damping_scale: jax.Array) -> mjx.Model:
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
