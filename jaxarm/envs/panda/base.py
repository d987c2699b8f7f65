"""`ArmBase`: what every arm task in MJX needs, once: its model on the device, ids, timing, IK, drawing.

A task builds its scene (an MjModel with the robot `ArmBase.robot` describes in it) and resolves its ids, whose
`robot` field holds the `RobotIds`; its env subclasses `ArmBase` and keeps only what is its own: the per-episode
model (`episode_model`), reset, transition, observation and reward, and how its per-episode geometry is drawn
(`_pose_for_drawing`). Nothing here knows about a task, and no task module is imported here.
"""

import abc
import copy
import dataclasses
from typing import Generic, NamedTuple, Protocol, TypeVar

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import mjx

from jaxarm import robots
from jaxarm.deploy.camera import DEPTH_RANGE
from jaxarm.deploy.limits import limit_targets
from jaxarm.envs.base import Env, EnvSpec, EnvState, HasEpisodeLimit, Observation
from jaxarm.envs.observation import check_obs_mode, observation_parts, pixel_observation
from jaxarm.envs.panda import camera
from jaxarm.envs.panda.mjx_impl import (
    Impl,
    check_no_overflow,
    pose_fixed_geoms,
    put_scene,
    raise_on_overflow,
    resolve_impl,
)
from jaxarm.envs.panda.render import Drawing
from jaxarm.envs.panda.robot import RobotIds, ik_arm_targets, solve_arm_posture, tcp_pose_at
from jaxarm.envs.panda.sim_to_real import with_noise
from jaxarm.robots import RobotDescription

CONTROL_DT = 0.04
"""Seconds of simulated time per env step, in every Panda task."""
WARP_TIMESTEP = 0.005
"""Longest physics timestep on Warp (a scene's finer one is kept); MJX-JAX keeps the scenes' own (0.01 s, the tosser's
0.004 s). MuJoCo C and Warp leave a servo whose force is clamped at its forcerange out of implicitfast's implicit
damping, MJX-JAX keeps it in. At 0.01 s the Panda's clamped servos then chatter on Warp exactly as in MuJoCo C
(joint speeds of 0.5-1.4 rad/s that move the joint by less than a milliradian): the scripted pick-and-place placed
32% of 1,024 objects (H100; 91% on MJX-JAX) and ppo_sorter learnt nothing in 52M env steps. At 0.005 s it places 82%
(H100) and ppo_sorter 87.5% after 3.4 minutes. At 0.04/6 s: 72% (64 envs, CPU); the wrist's damping x20 or its force
limit x3 changed nothing; dropping every arm force limit gave 83%, and 95% with 0.005 s, but Franka's torque limits
stay."""
CAMERAS = ("scene", "hand_camera")
"""The MJCF cameras a pixel observation stacks by default: the task's fixed scene camera and the wrist's."""


class ArmSim(struct.PyTreeNode):
    """The robot's share of every task's sim state: the physics that persists between steps, what the arm's
    control carries from one step to the next, and the noise and Warp records `ArmBase` keeps. A task's sim
    subclasses it and adds its own fields (J = the robot's arm joints, `ArmBase.arm_dof`; A = the task's actions).

    Attributes:
      qpos: [nq] generalized positions (the arm's J joints, then the fingers' 2, then the task's bodies).
      qvel: [nv] generalized velocities, in the same order.
      qacc_warmstart: [nv] the solver's warm start.
      ctrl: [J + 2] actuator targets (arm joints, then the fingers).
      target_velocity: [J] the arm's targets' rate of change over the last step (rad/s), which the robot's
        acceleration limits bound the next step's from (`ArmBase.limited_ctrl`).
      queued_actions: [L, A] the last L actions, newest first, not yet all applied (L = the env's
        `max_action_latency`; `action_latency` picks which one the servos receive).
      noise_key: PRNG key of the observation noise, split by the task at each step; the cameras' noise derives
        from it.
      overflow: [] int32: the Warp overflow bits (`mjx_impl.overflow_bits`) of every step since the first reset,
        which auto-resets keep (`ArmBase.carried_over`) until `ArmBase.checked` raises on them.
    """

    qpos: jax.Array
    qvel: jax.Array
    qacc_warmstart: jax.Array
    ctrl: jax.Array
    target_velocity: jax.Array
    queued_actions: jax.Array
    noise_key: jax.Array
    overflow: jax.Array


class CameraParams(Protocol):
    """What the cameras read of a task's params (`RobotParams`, which documents them; scalars)."""

    @property
    def camera_offset(self) -> camera.PoseOffset: ...

    @property
    def camera_gray_gain(self) -> jax.Array: ...

    @property
    def camera_gray_offset(self) -> jax.Array: ...

    @property
    def camera_depth_offset(self) -> jax.Array: ...

    @property
    def camera_depth_noise(self) -> jax.Array: ...

    @property
    def camera_finger_scale(self) -> jax.Array: ...


class IkParams(HasEpisodeLimit, CameraParams, Protocol):
    """What `ArmBase` reads of a task's params (scalars): the time limit, the IK's settings (`ArmParams`') and
    the cameras'."""

    @property
    def ik_damping(self) -> jax.Array: ...

    @property
    def ik_posture_gain(self) -> jax.Array: ...


class TaskIds(Protocol):
    """A task's ids: whatever it resolves for itself, with the robot's under `robot`."""

    @property
    def robot(self) -> RobotIds: ...


class RestingPhysics(NamedTuple):
    """The physics arrays of a robot at rest: qpos [nq], qvel [nv] and the solver's warm start [nv]."""

    qpos: jax.Array
    qvel: jax.Array
    qacc_warmstart: jax.Array


def image_channels(gray_and_depth: jax.Array, params: CameraParams, key: jax.Array) -> jax.Array:
    """float [..., 2C]: each camera's gray (0-1) then depth (metres) -> uint8 [..., 2C]: the gray times the params'
    `camera_gray_gain` plus their `camera_gray_offset`, and the depth plus `camera_depth_offset` and Gaussian noise
    of std `camera_depth_noise` (drawn from `key`, each pixel its own) over `DEPTH_RANGE`, each clipped to 0-1 and
    scaled to 0-255. The params' defaults leave the channels exactly as cast."""
    gray, depth = gray_and_depth[..., 0::2], gray_and_depth[..., 1::2]
    gray = gray * params.camera_gray_gain + params.camera_gray_offset
    depth = with_noise(depth + params.camera_depth_offset, key, params.camera_depth_noise)
    scaled = jnp.stack([gray, depth / DEPTH_RANGE], axis=-1).reshape(gray_and_depth.shape)
    return jnp.round(jnp.clip(scaled, 0.0, 1.0) * 255.0).astype(jnp.uint8)


@dataclasses.dataclass(frozen=True)
class ArmOptions:
    """How an arm env is built, whatever its task and robot: its physics, its buffers and what it observes. Frozen and
    hashable; configs set each field by name as a flat env kwarg (`env_kwargs.impl=warp`, `jaxarm.envs.registry`).

    Attributes:
      impl: MJX implementation of the physics: "jax", "warp" (NVIDIA's Warp; needs warp-lang and a CUDA GPU
        or the CPU) or "auto" (Warp on an NVIDIA GPU when warp-lang is importable, else JAX).
      max_envs: Warp only: its contact buffer, shared by all envs of a batch, holds `contacts_per_env` contacts
        for this many envs. Larger batches run while their contacts fit; a step that overflows raises.
      contacts_per_env: Warp only: contacts one env may have at once, and constraint rows for that many (default:
        the scene's worst case, every contact pair at its most). Smaller buffers step faster; a step that needs
        more raises.
      obs_mode: "state", "pixels" or "pixels+proprio" (`jaxarm.envs.observation`); the task builds its
        observation from `camera_image` in the pixel modes.
      resolution: side of the square camera images, pixels.
      cameras: names of the MJCF cameras (mode "fixed") stacked in `camera_image`.
      max_action_latency: the most control steps of action latency the params may ask for (`action_latency` of
        `RobotParams`); the state queues that many actions (`initial_action_queue`). The default covers the
        randomised presets' draws.
      privileged: a pixel mode's observation also holds the state observation of the same step
        ({"privileged": [S]}, for a learner's critic: `jaxarm.envs.observation`).
      robot: the arm the task is built on, by name (`jaxarm.robots.ROBOTS`).
    """

    impl: str = Impl.JAX
    max_envs: int = 4096
    contacts_per_env: int | None = None
    obs_mode: str = "state"
    resolution: int = 64
    cameras: tuple[str, ...] = CAMERAS
    max_action_latency: int = 2
    privileged: bool = False
    robot: str = "panda"

    def __post_init__(self):
        check_obs_mode(self.obs_mode, self.resolution, self.privileged)
        robots.robot(self.robot)  # raises naming the known robots
        if self.max_action_latency < 0:
            raise ValueError(f"max_action_latency must be >= 0, got {self.max_action_latency}")


ParamsT = TypeVar("ParamsT", bound=IkParams)
SimT = TypeVar("SimT", bound=ArmSim)
IdsT = TypeVar("IdsT", bound=TaskIds)


class ArmBase(Env[ParamsT, SimT], Generic[ParamsT, SimT, IdsT]):
    """Base of the arm envs: the compiled scene, its MJX copy and the robot's control, shared by every task.

    Args:
      mj_model: the task's compiled scene.
      ids: the task's ids, resolved in `mj_model`.
      start_tcp: [3] tool-centre position of the arm's start posture (`start_qpos`), pointing down; the IK's
        null space pulls the arm towards that posture.
      options: the construction choices every task shares (`ArmOptions`).

    Attributes:
      robot: the description of the robot the task is built on (`options.robot`: its home posture, joint limits,
        gripper).
      arm_dof: J, the arm's joint count: a ctrl vector holds the arm's J servo targets, then the fingers'.
      mj_model: the compiled scene as built (drawing poses a copy of it).
      ids: the task's ids; `ids.robot` the robot's.
      impl: the MJX implementation in use (`Impl.JAX` or `Impl.WARP`).
      substeps: physics steps per env step (`CONTROL_DT` over the model's timestep, at most `WARP_TIMESTEP` on Warp).
      mjx_model: `mj_model` on the device; tasks replace its per-episode fields in `episode_model`.
      home_tcp_rotation: [3, 3] tool-centre orientation at the robot's `home_qpos` (pointing down, yaw 0).
      start_qpos: [J] arm posture with the tool centre at `start_tcp` in `home_tcp_rotation`.
      obs_mode, resolution, max_action_latency, privileged: as in `options`.
      cameras: the `camera.Camera`s of `cameras`, resolved once (none in "state" mode).
      camera_names: their names in the MJCF (what a renderer outside JAX draws, `jaxarm.deploy.camera`).
    """

    uses_mjx = True
    draws_with_gl = True

    def __init__(
        self,
        mj_model: mujoco.MjModel,
        ids: IdsT,
        start_tcp: np.ndarray,
        options: ArmOptions,
    ):
        self.robot: RobotDescription = robots.robot(options.robot)
        self.arm_dof = len(self.robot.arm_joints)
        self.max_action_latency = options.max_action_latency
        self.obs_mode = options.obs_mode
        self.resolution = options.resolution
        self.privileged = options.privileged
        # Resolved only where they are observed: a state-only scene need not declare cameras, nor keep to the
        # primitive geoms the caster draws.
        self.cameras: tuple[camera.Camera, ...] = ()
        self.camera_names: tuple[str, ...] = ()
        self._camera_scene: camera.Scene | None = None
        if options.obs_mode != "state":
            self.camera_names = options.cameras
            self.cameras = tuple(camera.Camera.from_model(mj_model, name) for name in options.cameras)
            self._camera_scene = camera.Scene.from_model(mj_model)
        self.impl = resolve_impl(options.impl)
        if self.impl == Impl.WARP:
            mj_model = copy.copy(mj_model)  # the builders cache their models
            mj_model.opt.timestep = min(WARP_TIMESTEP, mj_model.opt.timestep)
        self.mj_model = mj_model
        self._drawing: Drawing | None = None
        self.ids = ids
        self.substeps = int(round(CONTROL_DT / mj_model.opt.timestep))
        self.mjx_model, self._data0 = put_scene(mj_model, self.impl, options.max_envs, options.contacts_per_env)
        self.home_tcp_rotation = tcp_pose_at(mj_model, ids.robot, self.robot.home_qpos)[1]
        self.start_qpos = self.solve_posture(start_tcp)

    def solve_posture(self, tcp_position: np.ndarray) -> np.ndarray:
        """Outside jit: [J] arm joints putting the tool centre at `tcp_position` [3] in `home_tcp_rotation`."""
        return solve_arm_posture(
            self.mj_model, self.ids.robot, self.robot.home_qpos, tcp_position, self.home_tcp_rotation
        )

    @abc.abstractmethod
    def episode_model(self, sim: SimT, params: ParamsT) -> mjx.Model:
        """`mjx_model` with this episode's (sim's) and the params' per-env fields replaced."""

    def resting(self, arm_q: jax.Array | np.ndarray, fingers: jax.Array | float) -> RestingPhysics:
        """The model's initial qpos with the arm at `arm_q` [J] and the fingers at `fingers` (each), at rest."""
        robot = self.ids.robot
        return RestingPhysics(
            qpos=self._data0.qpos.at[robot.arm_qpos].set(arm_q).at[robot.finger_qpos].set(fingers),
            qvel=jnp.zeros_like(self._data0.qvel),
            qacc_warmstart=jnp.zeros_like(self._data0.qacc_warmstart),
        )

    def kinematics(self, model: mjx.Model, sim: ArmSim) -> mjx.Data:
        """mjx.Data at the sim's state with positions, orientations and com-frame quantities (for Jacobians)."""
        return mjx.com_pos(model, self.poses(model, sim))

    def poses(self, model: mjx.Model, sim: ArmSim) -> mjx.Data:
        """mjx.Data at the sim's state with the bodies' and geoms' positions and orientations only."""
        data = self._data0.replace(qpos=sim.qpos, qvel=sim.qvel, ctrl=sim.ctrl, qacc_warmstart=sim.qacc_warmstart)
        with jax.named_scope("kinematics"):  # a phase of `bench profile`
            data = mjx.kinematics(model, data)
            if self.impl == Impl.WARP:
                data = pose_fixed_geoms(self.mj_model, model, data)
            return data

    def initial_action_queue(self) -> jax.Array:
        """float32 [max_action_latency, *action_shape]: an episode's queue of earlier actions, all zero."""
        return jnp.zeros((self.max_action_latency, *self.spec.action_shape), jnp.float32)

    @property
    def image_shape(self) -> tuple[int, int, int]:
        """Shape of `camera_image`: [R, R, 2 per camera]."""
        return (self.resolution, self.resolution, 2 * len(self.cameras))

    def observation_spec(self, state_size: int, proprio_size: int, action_size: int) -> EnvSpec:
        """The task's `EnvSpec`: a flat [state_size] observation in "state" mode; in a pixel mode the image, the
        [proprio_size] proprio ("pixels+proprio") and, with `privileged`, the [state_size] state observation."""
        if self.obs_mode == "state":
            return EnvSpec(observation_shape=(state_size,), action_shape=(action_size,))
        privileged_size = state_size if self.privileged else None
        parts = observation_parts(self.obs_mode, self.image_shape, proprio_size, privileged_size)
        return EnvSpec(observation_parts=parts, action_shape=(action_size,))

    def observation(self, state: jax.Array, proprio: jax.Array) -> Observation:
        """The task's observation in its mode from its state observation [S] and its proprio [P]: the state
        observation in "state" mode; else the pixel observation with `blank_image` (the base env draws it), and
        with `privileged` the state observation (without, XLA drops what only that part reads)."""
        if self.obs_mode == "state":
            return state
        privileged = state if self.privileged else None
        return pixel_observation(self.obs_mode, self.blank_image(), proprio.astype(jnp.float32), privileged)

    @property
    def draws_images(self) -> bool:
        return bool(self.cameras)

    def images(self, sim: SimT, params: ParamsT) -> jax.Array:
        """`camera_image` of `sim` posed in its episode's model, with the params' camera settings and this step's
        depth noise. The pixel observations of `_reset` and `_transition` hold `blank_image` instead, and the base
        env draws this once per step (see `jaxarm.envs.base`)."""
        model = self.episode_model(sim, params)
        # Folded, not split: the task splits `noise_key` itself at the next step, and a split here would hand the
        # images that step's state-observation key.
        key = jax.random.fold_in(sim.noise_key, 0)
        return self.camera_image(model, self.poses(model, sim), params, key, self.episode_luma(sim))

    def episode_luma(self, sim: SimT) -> jax.Array | np.ndarray:
        """[G] the brightness of each geom the cameras see (`camera.Scene.geoms`) in the sim's episode: the model's.
        A task whose surfaces take a gray of their own each episode overrides it."""
        return self.camera_scene.luma

    @property
    def camera_scene(self) -> camera.Scene:
        """What the cameras see of the model; ValueError in "state" mode, which has none."""
        if self._camera_scene is None:
            raise ValueError('obs_mode "state" has no camera: build the env with a pixel obs_mode')
        return self._camera_scene

    def camera_image(
        self,
        model: mjx.Model,
        data: mjx.Data,
        params: CameraParams,
        key: jax.Array,
        luma: jax.Array | np.ndarray | None = None,
    ) -> jax.Array:
        """uint8 [R, R, 2 per camera]: each camera's grayscale, then its depth over `DEPTH_RANGE`, cast in JAX
        (`camera.render`, each camera moved by the params' `camera_offset`) from the poses in `data` (after
        `poses`) and the episode's geom sizes, the fingers' times the params' `camera_finger_scale`, its geoms as
        bright as `luma` [G] where given (else as modelled), and put through `image_channels` with `params` and
        `key`."""
        scene = self.camera_scene
        offset = params.camera_offset
        geom_size = jnp.asarray(model.geom_size).at[self.ids.robot.finger_geoms].multiply(params.camera_finger_scale)
        channels = []
        for view in self.cameras:
            depth, gray = camera.render(
                scene,
                view,
                self.resolution,
                geom_size,
                data.geom_xpos,
                data.geom_xmat,
                data.xpos,
                data.xmat,
                offset,
                luma,
            )
            channels += [gray, depth]
        return image_channels(jnp.stack(channels, axis=-1), params, key)

    def simulate(self, model: mjx.Model, data: mjx.Data) -> mjx.Data:
        """`data` after `substeps` physics steps (one env step); raises if Warp dropped contacts on the way."""
        with jax.named_scope("physics"):  # a phase of `bench profile`
            data = jax.lax.fori_loop(0, self.substeps, lambda _, d: mjx.step(model, d), data)
            return check_no_overflow(data)

    def carried_over(self, ended: SimT, fresh: SimT) -> SimT:
        return fresh.replace(overflow=ended.overflow | fresh.overflow)

    def checked(self, state: EnvState[SimT]) -> EnvState[SimT]:
        """`state`, its sims' recorded overflow bits raised on if set (`mjx_impl.raise_on_overflow`)."""
        if self.impl == Impl.WARP:
            raise_on_overflow(state.sim.overflow)
        return state

    def limited_ctrl(self, ctrl: jax.Array, sim: SimT) -> tuple[jax.Array, jax.Array]:
        """Asked servo targets `ctrl` [J + 2] -> (the targets sent [J + 2], the arm's [J] rate of change, rad/s): the
        arm's path from the sim's targets kept within the robot's joint speed and acceleration limits
        (`limit_targets`, which the deployment loop applies to the same commands); the fingers' as asked."""
        arm = slice(self.arm_dof)
        limited = limit_targets(ctrl[arm], sim.ctrl[arm], sim.target_velocity, CONTROL_DT, self.robot.joint_limits)
        return ctrl.at[arm].set(limited.targets), limited.velocity

    def ik_targets(
        self,
        model: mjx.Model,
        data: mjx.Data,
        tcp_target: jax.Array,
        tcp_rotation: jax.Array | np.ndarray,
        params: ParamsT,
    ) -> jax.Array:
        """[J] arm joint targets moving the tool centre towards `tcp_target` [3] in `tcp_rotation` [3, 3]: one
        damped least-squares step with the params' damping, pulled towards `start_qpos` in its null space."""
        return ik_arm_targets(
            model,
            data,
            self.ids.robot,
            tcp_target,
            tcp_rotation,
            params.ik_damping,
            params.ik_posture_gain,
            self.start_qpos,
        )

    def at_servo_targets(self, model: mjx.Model, data: mjx.Data) -> mjx.Data:
        """`data` with the arm posed at its servo targets `data.ctrl[:J]` (kinematics and com-frame quantities,
        for Jacobians): where the servos are taking the tool."""
        posed = data.qpos.at[self.ids.robot.arm_qpos].set(data.ctrl[: self.arm_dof])
        return mjx.com_pos(model, mjx.kinematics(model, data.replace(qpos=posed)))

    def servo_ik_targets(
        self,
        model: mjx.Model,
        servo_data: mjx.Data,
        tcp_target: jax.Array,
        tcp_rotation: jax.Array | np.ndarray,
        params: ParamsT,
    ) -> jax.Array:
        """[J] arm joint targets putting the tool centre at `tcp_target` [3] in `tcp_rotation` [3, 3], from where the
        servos are taking the tool (`servo_data`, from `at_servo_targets`): a running target's differential IK, so
        what the servos chase moves by the target's change alone, where IK from the measured pose would start each
        step the servos' lag behind. `ik_targets`, then a second damped step without the posture pull: the first
        leaves 2-7% of a 1 cm move undone (its damping, and the pull's leak into the tool's motion), which would
        slow the tool as much."""
        joints = self.ik_targets(model, servo_data, tcp_target, tcp_rotation, params)
        servo_ctrl = servo_data.ctrl.at[: self.arm_dof].set(joints)
        servo_data = self.at_servo_targets(model, servo_data.replace(ctrl=servo_ctrl))
        ids, damping = self.ids.robot, params.ik_damping
        return ik_arm_targets(model, servo_data, ids, tcp_target, tcp_rotation, damping, 0.0, self.start_qpos)

    def render(
        self, state: EnvState[SimT], params: ParamsT, height: int = 240, width: int = 320, camera: str = "front"
    ) -> np.ndarray:
        """One (non-batched) state -> [height, width, 3] uint8 RGB frame seen from `camera` (outside jit).

        The env keeps one copy of its model for drawing (the episode's geometry is written into it each frame;
        `mj_model` stays as built) and one renderer per frame size: the sorter at 320x240 with EGL on the 2-core
        CPU drew a frame in 170-200 ms with a renderer built for it, 57 ms with one reused.
        """
        if self._drawing is None:
            self._drawing = Drawing(copy.copy(self.mj_model))
        self._pose_for_drawing(self._drawing.model, state.sim, params)
        return self._drawing.render(np.asarray(state.sim.qpos), height, width, camera)

    @abc.abstractmethod
    def _pose_for_drawing(self, model: mujoco.MjModel, sim: SimT, params: ParamsT) -> None:
        """Writes the episode's geometry (what `episode_model` replaces per env) into `model`, a copy of
        `mj_model` about to be drawn."""
