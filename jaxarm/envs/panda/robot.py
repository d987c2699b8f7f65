"""A robot arm in a task's scene, read from its `RobotDescription`: the scene with the robot's model file, its ids,
and end-effector control by IK.

The robot's model file (the Panda's `assets/panda.xml`) is included by each env's scene. Control here is pure JAX on
mjx.Data: damped least-squares IK of the tool centre (position and a held orientation) with a null-space pull
towards the home posture, turned into joint position targets for the arm's servos. Nothing here knows about a task.
"""

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxarm.envs.panda.dynamics import set_dynamics
from jaxarm.robots import PANDA, RobotDescription


@dataclasses.dataclass(frozen=True)
class RobotIds:
    """Indices of the robot in a compiled scene, resolved once (numpy ints / arrays, static under jit).

    Attributes:
      arm_qpos: [J] qpos addresses of the arm joints (also their dof addresses: the arm comes first; J: the arm's
        joint count, `RobotDescription.arm_joints`).
      finger_qpos: [2] qpos addresses of the finger joints.
      finger_geoms: ids of the geoms on the fingers' bodies.
      hand_body: body id of the hand.
      tcp_site: site id of the tool centre point (between the finger pads).
      arm_limits: [J, 2] arm joint ranges.
      arm_actuators: [J] actuator ids of the arm joints' servos.
    """

    arm_qpos: np.ndarray
    finger_qpos: np.ndarray
    finger_geoms: np.ndarray
    hand_body: int
    tcp_site: int
    arm_limits: np.ndarray
    arm_actuators: np.ndarray


SCENE_ROBOT_INCLUDE = 'file="../../panda/assets/panda.xml"'
"""How every task's scene.xml includes its robot: jaxarm's Panda, which `scene_spec` replaces with another model."""


def scene_spec(scene_xml: Path, robot: RobotDescription, dynamics: str, robot_xml: Path | None = None) -> mujoco.MjSpec:
    """The MjSpec of a task's `scene_xml` with `robot` in it and its `dynamics` (`dynamics.DYNAMICS`): the
    robot's model is its description's `model_xml`, or `robot_xml` (another with the names of its description),
    included in place of jaxarm's Panda."""
    model_xml = robot_xml or robot.model_xml
    if model_xml == PANDA.model_xml:
        spec = mujoco.MjSpec.from_file(str(scene_xml))
    else:
        text = scene_xml.read_text()
        if SCENE_ROBOT_INCLUDE not in text:
            raise ValueError(f"{scene_xml} does not include its robot as {SCENE_ROBOT_INCLUDE}")
        spec = mujoco.MjSpec.from_string(text.replace(SCENE_ROBOT_INCLUDE, f'file="{model_xml.resolve()}"'))
    set_dynamics(spec, dynamics, robot)
    return spec


def resolve_robot_ids(model: mujoco.MjModel, robot: RobotDescription) -> RobotIds:
    """Looks up the ids of `robot` in `model` by the names of its description."""
    joint = model.joint
    finger_bodies = [joint(name).bodyid[0] for name in robot.finger_joints]
    return RobotIds(
        arm_qpos=np.array([joint(name).qposadr[0] for name in robot.arm_joints]),
        finger_qpos=np.array([joint(name).qposadr[0] for name in robot.finger_joints]),
        finger_geoms=np.flatnonzero(np.isin(model.geom_bodyid, finger_bodies)),
        hand_body=model.body(robot.hand_body).id,
        tcp_site=model.site(robot.tcp_site).id,
        arm_limits=np.stack([joint(name).range for name in robot.arm_joints]),
        arm_actuators=np.array([model.actuator(name).id for name in robot.arm_actuators]),
    )


def tcp_pose_at(model: mujoco.MjModel, ids: RobotIds, arm_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics outside jit: [J] arm joints -> (tool centre position [3], rotation [3, 3])."""
    data = mujoco.MjData(model)
    data.qpos[ids.arm_qpos] = arm_q
    mujoco.mj_kinematics(model, data)
    return data.site_xpos[ids.tcp_site].copy(), data.site_xmat[ids.tcp_site].reshape(3, 3).astype(np.float32)


def solve_arm_posture(
    model: mujoco.MjModel,
    ids: RobotIds,
    home_qpos: np.ndarray,
    tcp_position: np.ndarray,
    rotation: np.ndarray,
    iterations: int = 200,
) -> np.ndarray:
    """Outside jit: [J] arm joints, from `home_qpos` [J], putting the tool centre at `tcp_position` with `rotation`.

    Raises ValueError if the IK does not reach the pose within 0.1 mm (out of reach or at a joint limit).
    Its steps run on the CPU backend whatever the default device: on a GPU each of them would be a launch and
    two copies, and its compile one more kernel build, in every process that builds the env.
    """
    data = mujoco.MjData(model)
    arm_q = home_qpos.astype(np.float64)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    with jax.default_device(host_device()):
        for _ in range(iterations):
            data.qpos[ids.arm_qpos] = arm_q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_jacSite(model, data, jacp, jacr, ids.tcp_site)
            step, error = _posture_step(
                np.concatenate([jacp, jacr])[:, ids.arm_qpos],
                tcp_position - data.site_xpos[ids.tcp_site],
                data.site_xmat[ids.tcp_site].reshape(3, 3),
                rotation,
            )
            arm_q = np.clip(arm_q + np.asarray(step), ids.arm_limits[:, 0], ids.arm_limits[:, 1])
    error = np.asarray(error)
    if np.linalg.norm(error[:3]) > 1e-4:
        raise ValueError(f"no arm posture puts the tool centre at {tcp_position} (error {error[:3]})")
    return arm_q.astype(np.float32)


def host_device() -> jax.Device | None:
    """This process's CPU device (with jax.distributed, `jax.devices("cpu")[0]` is process 0's, which another process
    cannot compute on), or None (the default device) where JAX_PLATFORMS left the CPU out."""
    try:
        return jax.local_devices(backend="cpu")[0]
    except RuntimeError:
        return None


@jax.jit
def _posture_step(
    jacobian: np.ndarray, position_error: np.ndarray, rotation: np.ndarray, target_rotation: np.ndarray
) -> tuple[jax.Array, jax.Array]:
    """One step of `solve_arm_posture`: ([J] joint step, [6] task error). Compiled once, because the same
    operations dispatched one by one took 2.6 s of the 200-iteration solve on the 2-core CPU (0.3 s compiled)."""
    error = jnp.concatenate([position_error, rotation_error(rotation, target_rotation)])
    step, _ = damped_least_squares(jacobian, error, 1e-3)
    return step, error


def damped_least_squares(
    jacobian: jax.Array | np.ndarray, error: jax.Array | np.ndarray, damping
) -> tuple[jax.Array, jax.Array]:
    """[6, J] Jacobian, [6] task error -> ([J] joint step, [J, J] null-space projector).

    dq = Jᵀ(JJᵀ + λ²I)⁻¹ e; the projector I − Jᵀ(JJᵀ + λ²I)⁻¹J passes posture motions the task does not
    see.
    """
    gram = jacobian @ jacobian.T + damping**2 * jnp.eye(jacobian.shape[0])
    solved = jnp.linalg.solve(gram, jnp.concatenate([error[:, None], jacobian], axis=1))
    step = jacobian.T @ solved[:, 0]
    projector = jnp.eye(jacobian.shape[1]) - jacobian.T @ solved[:, 1:]
    return step, projector


def rotation_error(rotation: jax.Array | np.ndarray, target: jax.Array | np.ndarray) -> jax.Array:
    """[3, 3] current and target rotation matrices -> [3] world-frame axis·angle error (small-angle form)."""
    return 0.5 * jnp.sum(jnp.cross(rotation.T, target.T), axis=0)


def yaw_of_rotation(rotation: jax.Array) -> jax.Array:
    """[..., 3, 3] rotation matrices -> [...] heading of their x axis in the horizontal plane (radians)."""
    return jnp.arctan2(rotation[..., 1, 0], rotation[..., 0, 0])


def wrapped_angle(angle: jax.Array) -> jax.Array:
    """[...] angles (radians) -> the same directions in (-pi, pi]."""
    return jnp.arctan2(jnp.sin(angle), jnp.cos(angle))


def advanced_target(chased: jax.Array, step: jax.Array, measured: jax.Array, lead: jax.Array) -> jax.Array:
    """A running target's next value, [...] like `chased`: the target the servos chase moved by `step`, held
    within `lead` of the `measured` pose per element, so a blocked arm presses no harder than the lead makes its
    servos and a free one moves by the step once under way."""
    return jnp.clip(chased + step, measured - lead, measured + lead)


def yaw_of_quaternion(quat: jax.Array) -> jax.Array:
    """[..., 4] unit quaternions (w, x, y, z) -> [...] heading of the rotated x axis (radians)."""
    w, x, y, z = jnp.moveaxis(quat, -1, 0)
    return jnp.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))


def rotation_about_z(angle: jax.Array) -> jax.Array:
    """[] angle -> [3, 3] rotation about the vertical."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(angle), jnp.ones_like(angle)
    return jnp.stack([jnp.stack([c, -s, zero]), jnp.stack([s, c, zero]), jnp.stack([zero, zero, one])])


def tcp_jacobian(model: mjx.Model, data: mjx.Data, ids: RobotIds) -> jax.Array:
    """[6, nv] Jacobian of the tool centre: linear rows, then angular rows. `data` needs com_pos."""
    jacp, jacr = mjx.jac(model, data, data.site_xpos[ids.tcp_site], ids.hand_body)
    return jnp.concatenate([jacp.T, jacr.T])


def ik_arm_targets(
    model: mjx.Model,
    data: mjx.Data,
    ids: RobotIds,
    tcp_target: jax.Array,
    tcp_rotation: jax.Array | np.ndarray,
    damping,
    posture_gain,
    posture: np.ndarray,
) -> jax.Array:
    """[J] arm joint targets moving the tool centre towards `tcp_target` [3] with `tcp_rotation` [3, 3].

    One damped least-squares step from the measured joints, plus `posture_gain` of the way to `posture` [J]
    in the null space of the tool pose, clipped to the joint limits.
    """
    arm_q = data.qpos[ids.arm_qpos]
    tcp = data.site_xpos[ids.tcp_site]
    current = data.site_xmat[ids.tcp_site].reshape(3, 3)
    error = jnp.concatenate([tcp_target - tcp, rotation_error(current, tcp_rotation)])
    jacobian = tcp_jacobian(model, data, ids)[:, ids.arm_qpos]
    step, projector = damped_least_squares(jacobian, error, damping)
    pull = projector @ (posture_gain * (posture - arm_q))
    return jnp.clip(arm_q + step + pull, ids.arm_limits[:, 0], ids.arm_limits[:, 1])
