"""The Panda sorter: a Franka Panda puts cubes, cylinders and spheres into the bin of their shape, in MJX.

One env step is `CONTROL_DT` = 0.04 s: the action becomes joint position targets (through damped
least-squares IK in `ee` mode), moved within Franka's joint speed and acceleration limits
(`ArmBase.limited_ctrl`), then MJX takes several physics substeps. An object whose centre enters a bin
(inside its walls, below the rim) is scored: +500 in the bin of its shape, +200 in another. One that drops
below the table top is penalised (-50). Either way it leaves play and is parked far away, at rest, for the
rest of the episode, so it can never be scored twice or touch anything again. The episode terminates when
no object is left in play and succeeds when all of them went into their own bins. Dense shaping is
potential-based, so no behaviour can farm it (reward.py).

This module is the env's contract: spec, reset, transition, control and observation. The robot's set-up
is `ArmBase`'s; the objects' geometry, spawning and parking are objects.py's; scoring and shaping
reward.py's; the training start states curriculum.py's.

The env holds the mjx.Model (static). Per-episode object shapes and sizes, and the randomised params
(friction, density, mass scale), enter by replacing mjx.Model fields inside the step, so vmap over
states and params is per-env domain randomisation. The sim state keeps only what the physics needs
between steps (qpos, qvel, ctrl, solver warm start), not a whole mjx.Data.

`obs_mode` "pixels" observes {"image": uint8 [R, R, 4]}, grayscale and depth of a fixed camera above the table
and of the wrist camera (`ArmBase.camera_image`); "pixels+proprio" adds the tool's part of the state
observation, {"proprio": [21]} ([28] with `running_target`); the objects then show only in the images.
"""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxarm.envs.base import Env, Observation, Transition
from jaxarm.envs.panda.base import ArmBase, ArmOptions
from jaxarm.envs.panda.dynamics import NOMINAL
from jaxarm.envs.panda.mjx_impl import overflow_bits, with_geom_sizes
from jaxarm.envs.panda.robot import (
    advanced_target,
    rotation_about_z,
    tcp_jacobian,
    wrapped_angle,
    yaw_of_quaternion,
    yaw_of_rotation,
)
from jaxarm.envs.panda.sim_to_real import delayed_action, with_noise, with_robot_params
from jaxarm.envs.panda_sort.curriculum import draw_start, place_in_hand, wound_up_posture
from jaxarm.envs.panda_sort.layout import make_layout
from jaxarm.envs.panda_sort.model import ModelIds, build_model, resolve_ids
from jaxarm.envs.panda_sort.objects import (
    object_geom_sizes,
    object_mass_inertia,
    object_positions,
    park,
    pose_index,
    spawn_xy,
    velocity_index,
)
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.envs.panda_sort.render import dress_objects
from jaxarm.envs.panda_sort.reward import (
    IN_CORRECT_BIN,
    IN_PLAY,
    SHAPING_TERMS,
    PandaSortInfo,
    RewardTerms,
    carry_targets,
    next_outcome,
    next_target,
    reward_terms,
    shaping_potential,
    step_info,
)
from jaxarm.envs.panda_sort.sim import PandaSortSim
from jaxarm.robots import PANDA

MODE_EE = "ee"
MODE_JOINT = "joint"
TOOL_POSE_OBS_SIZE = 14
"""The tool's part of the observation, after the objects', up to the arm's joint angles (`PandaSort._observe`):
the tool's J joint angles follow, then with `running_target` each arm joint's servo target minus its angle (J)."""
OBJECT_OBS_SIZE = 26
"""Per object: position 3, quaternion 4, linear and angular velocity 6, one-hot shape 3, size 1, in play 1,
then what a policy would otherwise have to compute: object − tool centre 3, carry target − object 3, and
the object's yaw relative to the hand as cos and sin of 4·Δyaw (a cube and the octagonal cylinder look the
same every 90 degrees)."""
OBJECT_RELATIVE_YAW = slice(OBJECT_OBS_SIZE - 2, OBJECT_OBS_SIZE)
"""Where cos and sin of 4·Δyaw sit in an object's observation."""
OBJECT_CARRY_TARGET = slice(OBJECT_OBS_SIZE - 5, OBJECT_OBS_SIZE - 2)
"""Where carry target − object sits in an object's observation."""
START_HEIGHT = 0.25
"""Tool-centre height at reset, pointing down over the middle of the spawn region (the Panda's ready pose is
twice as high, 70 steps of descent away)."""
GRASP_HEIGHT = 0.02
"""Tool-centre height of a grasp-ready start: the pads (24 mm tall) span every object's centre height."""
TCP_MIN_Z = 0.01
"""Lowest tool-centre target: the arm has no contact with the table, so IK must not drive it through."""


class PandaSort(ArmBase[PandaSortParams, PandaSortSim, ModelIds]):
    """Franka Panda sorting `objects_count` objects into three shape bins.

    Args:
      objects_count: number of object slots, 1 to 5 (static: fixes shapes and the contact set).
      control_mode: "ee" (tool-centre delta xyz, a turn of the hand about the vertical, and a finger command;
        5 actions; the tool keeps pointing down) or "joint" (J joint-target deltas and a finger command; J + 1
        actions, J the robot's arm joints). The finger command maps [-1, 1] to closed..open.
      blocker: adds a thin bar between the spawn region and the bins.
      tosser: puts the bins on a second table out of the arm's reach: objects must be thrown (layout.py); the
        fingers' contacts are stiffer and the physics steps 2.5 times finer (model.FIRM_GRIP_TIMESTEP), so that a
        held object rides a throw.
      target_first: one object at a time is the target (`PandaSortSim.target`): the observation lists the
        objects starting from it (slots in cyclic order), and the shaping terms follow it alone, so a policy
        always finds the object to work on in the first slot and several objects become the one-object task
        repeated. With one object nothing changes.
      dynamics: the robot's link inertials and joint friction: "nominal" (its model file's) or "identified" (its
        description's identified links, the Panda's from Franka's published values: `jaxarm.envs.panda.dynamics`).
      running_target: an action moves the target the servos chase (the tool-centre pose in `ee` mode, the joint
        targets in `joint` mode) by `ee_step`, `ee_yaw_step` or `joint_step` per unit, held within `max_lead`,
        `max_yaw_lead` or `max_joint_lead` of what is measured, so a step's action is the motion it gets once
        under way; the observation adds the servos' lead (J values). Without it (the default) each
        step's target starts from the measured pose and the servos cover about a third of the step.
      options: the physics, its buffers and the observation (`ArmOptions`; the module docstring says what each
        observation mode holds).
    """

    # jaxlib 0.10.2's CPU runtime deadlocked on this env at 256 envs (one object) and 128 (three): two batched
    # Cholesky factorisations of MJX waited on each other in its two-worker pool.
    cpu_max_envs = 64

    def __init__(
        self,
        objects_count: int = 1,
        control_mode: str = MODE_EE,
        blocker: bool = False,
        tosser: bool = False,
        target_first: bool = False,
        dynamics: str = NOMINAL,
        running_target: bool = False,
        *,
        options: ArmOptions = ArmOptions(),
    ):
        if not 1 <= objects_count <= 5:
            raise ValueError(f"objects_count must be in 1..5, got {objects_count}")
        if control_mode not in (MODE_EE, MODE_JOINT):
            raise ValueError(f"control_mode must be {MODE_EE!r} or {MODE_JOINT!r}, got {control_mode!r}")
        self.objects_count = objects_count
        self.control_mode = control_mode
        self.target_first = target_first
        self.running_target = running_target
        self.tosser = tosser
        if tosser and options.robot != PANDA.name:
            raise ValueError(f"the tosser's throw is the Panda's (its wind-up postures), not the {options.robot}'s")
        self.layout = make_layout(blocker=blocker, tosser=tosser)
        mj_model = build_model(objects_count, self.layout, dynamics, firm_grip=tosser, robot=options.robot)
        spawn_centre = (np.array(self.layout.spawn_low) + np.array(self.layout.spawn_high)) / 2
        start_tcp = np.r_[spawn_centre, START_HEIGHT]
        ids = resolve_ids(mj_model, objects_count, options.robot)
        super().__init__(mj_model, ids, start_tcp, options)
        self.grasp_qpos = self.solve_posture(np.r_[spawn_centre, GRASP_HEIGHT])
        self.tool_obs_size = TOOL_POSE_OBS_SIZE + self.arm_dof * (2 if running_target else 1)
        state_size = OBJECT_OBS_SIZE * objects_count + self.tool_obs_size
        action_size = 5 if control_mode == MODE_EE else self.arm_dof + 1
        self.spec = self.observation_spec(state_size, self.tool_obs_size, action_size)

    def default_params(self) -> PandaSortParams:
        return PandaSortParams()

    def observation_source_index(self, source: Env) -> np.ndarray:
        """As `Env.observation_source_index`; from a sorter with another object count (same control mode), the
        object rows they share map row to row (with `target_first`, a one-object learner's object becomes the
        target) and the tool's inputs map onto each other; the extra objects' inputs, and the servos' lead where
        only this env observes it, are new (−1). So is carry target − object where the source's bins stand in
        another arrangement (`bins_moved_from`); where they all moved by one displacement, it maps and
        `observation_source_shift` says how much more it reads."""
        sorter = self.row_source(source)
        if sorter is None:
            return super().observation_source_index(source)
        shared = min(sorter.objects_count, self.objects_count)
        objects = np.full((self.objects_count, OBJECT_OBS_SIZE), -1)
        objects[:shared] = np.arange(shared * OBJECT_OBS_SIZE).reshape(shared, OBJECT_OBS_SIZE)
        if self.bins_moved_from(sorter) is None:
            objects[:, OBJECT_CARRY_TARGET] = -1
        source_tool = sorter.objects_count * OBJECT_OBS_SIZE + np.arange(sorter.tool_obs_size)
        tool = np.full(self.tool_obs_size, -1)
        shared_tool = min(sorter.tool_obs_size, self.tool_obs_size)
        tool[:shared_tool] = source_tool[:shared_tool]
        return np.concatenate([objects.ravel(), tool])

    def observation_source_shift(self, source: Env) -> np.ndarray:
        """As `Env.observation_source_shift`: carry target − object of each shared object reads the bins'
        displacement (`bins_moved_from`) more than in the source. From the sorter, the tosser's bins stand 0.97 m
        farther, eight times that input's spread over the sorter's starts (0.12 m): read unshifted, the first
        stage's policy grasped none of 32 objects from rest in the tosser, as new inputs (at their mean) 31%, moved
        all, each at the step it grasps in its own env (docs/benchmarks-log.md, 2026-11-30)."""
        sorter = self.row_source(source)
        if sorter is None or (moved := self.bins_moved_from(sorter)) is None:
            return super().observation_source_shift(source)
        shared = min(sorter.objects_count, self.objects_count)
        objects = np.zeros((self.objects_count, OBJECT_OBS_SIZE), np.float32)
        objects[:shared, OBJECT_CARRY_TARGET] = moved
        return np.concatenate([objects.ravel(), np.zeros(self.tool_obs_size, np.float32)])

    def row_source(self, source: Env) -> "PandaSort | None":
        """`source` where it is a sorter whose observation maps onto this one's row by row (both flat, the same
        control mode); None otherwise."""
        flat = self.spec.flat_observation and source.spec.flat_observation
        if flat and isinstance(source, PandaSort) and source.control_mode == self.control_mode:
            return source
        return None

    def bins_moved_from(self, source: "PandaSort") -> np.ndarray | None:
        """[3] (dx, dy, 0): how far every bin of this env stands from the same shape's bin in `source`'s layout;
        None where the bins moved by different amounts."""
        moved = np.array(self.layout.bin_centers) - np.array(source.layout.bin_centers)
        if not np.allclose(moved, moved[0]):
            return None
        return np.r_[moved[0], 0.0].astype(np.float32)

    # --- the physics model of one env -------------------------------------------------------------

    def episode_model(self, sim: PandaSortSim, params: PandaSortParams) -> mjx.Model:
        """The mjx.Model with this episode's object shapes and sizes and the params' randomisation (objects'
        masses and friction, the robot's `RobotParams`)."""
        ids, model = self.ids, self.mjx_model
        geom_ids = ids.object_geom.ravel()
        sizes = object_geom_sizes(sim.shape, sim.size).reshape(-1, 3)
        is_sphere = jnp.tile(jnp.array([False, False, True]), self.objects_count)
        rbound = jnp.where(is_sphere, sizes[:, 0], jnp.linalg.norm(sizes, axis=-1))
        mass, inertia = object_mass_inertia(sim.shape, sim.size, params.density)
        mass, inertia = mass * params.mass_scale, inertia * params.mass_scale
        invweight = jnp.stack([1.0 / mass, jnp.mean(1.0 / inertia, axis=-1)], -1)
        friction = model.pair_friction.at[ids.finger_pair, :2].set(params.finger_friction)
        friction = friction.at[ids.object_pair, :2].set(params.object_friction)
        model = with_robot_params(model, ids.robot, params)
        return with_geom_sizes(model, geom_ids, sizes, rbound).replace(
            body_mass=model.body_mass.at[ids.object_body].set(mass),
            body_inertia=model.body_inertia.at[ids.object_body].set(inertia),
            body_invweight0=model.body_invweight0.at[ids.object_body].set(invweight),
            # Each object is a free body of its own: its subtree is itself (Warp's com_pos reads this; JAX's sums).
            body_subtreemass=model.body_subtreemass.at[ids.object_body].set(mass),
            pair_friction=friction,
        )

    def _pose_for_drawing(self, model: mujoco.MjModel, sim: PandaSortSim, params: PandaSortParams) -> None:
        dress_objects(model, self.ids, np.asarray(sim.shape), np.asarray(sim.size), np.asarray(sim.colour))

    # --- control ------------------------------------------------------------------------------------

    def _arm_targets(self, model, data, action, params) -> jax.Array:
        """[J] arm joint targets from the action: IK towards the displaced and turned tool, or joint deltas;
        from the measured pose, or with `running_target` from the servos' targets (`data.ctrl`), held within
        the params' leads of the measured pose."""
        robot = self.ids.robot
        if self.control_mode == MODE_JOINT:
            arm_q, step = data.qpos[robot.arm_qpos], action[: self.arm_dof] * params.joint_step
            if self.running_target:
                joints = advanced_target(data.ctrl[: self.arm_dof], step, arm_q, params.max_joint_lead)
            else:
                joints = arm_q + step
            return jnp.clip(joints, robot.arm_limits[:, 0], robot.arm_limits[:, 1])
        tcp = data.site_xpos[robot.tcp_site]
        yaw = yaw_of_rotation(data.site_xmat[robot.tcp_site].reshape(3, 3))
        if self.running_target:
            data = self.at_servo_targets(model, data)
            chased_tcp = data.site_xpos[robot.tcp_site]
            chased_yaw = yaw_of_rotation(data.site_xmat[robot.tcp_site].reshape(3, 3))
            target = advanced_target(chased_tcp, action[:3] * params.ee_step, tcp, params.max_lead)
            turn = wrapped_angle(chased_yaw + action[3] * params.ee_yaw_step - yaw)
            target_yaw = yaw + jnp.clip(turn, -params.max_yaw_lead, params.max_yaw_lead)
        else:
            target = tcp + action[:3] * params.ee_step
            target_yaw = yaw + action[3] * params.ee_yaw_step
        target = target.at[2].set(jnp.maximum(target[2], TCP_MIN_Z))
        # The home tool frame has yaw 0, so turning it about z by the target yaw gives a pointing-down target.
        rotation = rotation_about_z(target_yaw) @ self.home_tcp_rotation
        if self.running_target:
            return self.servo_ik_targets(model, data, target, rotation, params)
        return self.ik_targets(model, data, target, rotation, params)

    def _ctrl(self, model, data, action, params) -> jax.Array:
        finger = (action[-1] + 1.0) * (self.robot.finger_open / 2)
        return jnp.concatenate([self._arm_targets(model, data, action, params), jnp.stack([finger, finger])])

    # --- observation and shaping ----------------------------------------------------------------------

    def _observe(
        self, model: mjx.Model, data: mjx.Data, sim: PandaSortSim, params: PandaSortParams, key: jax.Array
    ) -> Observation:
        """[OBJECT_OBS_SIZE N + tool_obs_size]: per object (zeros when out of play) OBJECT_OBS_SIZE values, then tool
        centre position 3, orientation quaternion 4, linear and angular velocity 6, finger width 1, and the J
        arm joint angles (the Panda is redundant, so the tool pose alone does not tell its posture or nearness
        to joint limits); with `running_target`, then each arm joint's servo target minus its angle (J). Robot
        quantities come from `data`, object quantities from `sim`, the objects' positions off by the episode's
        pose-estimate error; `key` draws the params' object-pose and observation noise.
        """
        robot = self.ids.robot
        pose_key, objects_key, tool_key = jax.random.split(key, 3)
        in_play = (sim.outcome == IN_PLAY)[:, None]
        pose = sim.qpos[pose_index(self.ids)]
        estimate = pose[:, :3] + params.object_pose_bias * sim.pose_error
        pose = pose.at[:, :3].set(with_noise(estimate, pose_key, params.object_pose_noise))
        velocity = sim.qvel[velocity_index(self.ids)]
        tcp = data.site_xpos[robot.tcp_site]
        relative_yaw = yaw_of_quaternion(pose[:, 3:]) - yaw_of_rotation(data.site_xmat[robot.tcp_site].reshape(3, 3))
        objects = jnp.concatenate(
            [
                pose,
                velocity,
                jax.nn.one_hot(sim.shape, 3),
                sim.size[:, None],
                in_play.astype(jnp.float32),
                pose[:, :3] - tcp,
                carry_targets(self.layout, sim.shape, params.carry_height) - pose[:, :3],
                jnp.cos(4.0 * relative_yaw)[:, None],
                jnp.sin(4.0 * relative_yaw)[:, None],
            ],
            -1,
        )
        tcp_velocity = tcp_jacobian(model, data, robot) @ sim.qvel
        tool = [
            tcp,
            data.xquat[robot.hand_body],
            tcp_velocity,
            jnp.sum(sim.qpos[robot.finger_qpos])[None],
            sim.qpos[robot.arm_qpos],
        ]
        if self.running_target:
            tool.append(sim.ctrl[: self.arm_dof] - sim.qpos[robot.arm_qpos])
        tool_obs = with_noise(jnp.concatenate(tool), tool_key, params.obs_noise)
        objects = with_noise(objects, objects_key, params.obs_noise) * in_play
        state = jnp.concatenate([objects[self.slot_order(sim)].ravel(), tool_obs]).astype(jnp.float32)
        return self.observation(state, tool_obs)

    def slot_order(self, sim: PandaSortSim) -> jax.Array:
        """[N] the object slots in the order the observation lists them: from the target on with
        `target_first`, else as they are."""
        slots = jnp.arange(self.objects_count)
        return (sim.target + slots) % self.objects_count if self.target_first else slots

    def shaping_potential(self, data: mjx.Data, sim: PandaSortSim, params: PandaSortParams) -> jax.Array:
        """[S] weighted shaping potentials of `sim` (reward.shaping_potential), `data` its kinematics."""
        return shaping_potential(self.ids, self.layout, data, sim, params, self.target_first)

    # --- the contract -------------------------------------------------------------------------------

    def _reset(self, key: jax.Array, params: PandaSortParams) -> tuple[PandaSortSim, jax.Array, PandaSortInfo]:
        shape_key, size_key, colour_key, spawn_key, yaw_key, arm_key, start_key = jax.random.split(key, 7)
        # A separate stream for the multi-object curricula, so one-object episodes draw as they always did.
        start = draw_start(start_key, jax.random.fold_in(key, 1), self.objects_count, params)
        n, ids = self.objects_count, self.ids
        shape = jax.random.randint(shape_key, (n,), 0, 3).astype(jnp.int32)
        scale = jax.random.uniform(size_key, (n,), minval=params.size_scale_low, maxval=params.size_scale_high)
        size = params.object_size * scale
        xy = spawn_xy(
            spawn_key,
            n,
            self.layout,
            params.object_size * params.size_scale_high * np.sqrt(2.0),
            jnp.where(start.ready, start.focus, -1),
        )
        yaw = jax.random.uniform(yaw_key, (n,), maxval=2 * jnp.pi)
        # Resting on the table, 1 mm above it, turned about z.
        zero = jnp.zeros(n)
        pose = jnp.stack([xy[:, 0], xy[:, 1], size + 0.001, jnp.cos(yaw / 2), zero, zero, jnp.sin(yaw / 2)], -1)
        noise = jax.random.uniform(arm_key, (self.arm_dof,), minval=-params.home_noise, maxval=params.home_noise)
        arm_q = (1.0 - start.blend) * self.grasp_qpos + start.blend * self.start_qpos + noise
        if self.tosser:
            own_bin = jnp.asarray(self.layout.bin_centers)[shape[start.focus]]
            wound_up = arm_q + start.wind_up * (wound_up_posture(own_bin) + noise - arm_q)
            arm_q = jnp.where(start.wound_up, wound_up, arm_q)
        resting = self.resting(arm_q, self.robot.finger_open)
        qpos = resting.qpos.at[pose_index(ids)].set(pose)
        outcome = jnp.where(start.presorted, IN_CORRECT_BIN, IN_PLAY).astype(jnp.int32)
        qpos, qvel = park(ids, qpos, resting.qvel, outcome != IN_PLAY)
        sim = PandaSortSim(
            qpos=qpos,
            qvel=qvel,
            qacc_warmstart=resting.qacc_warmstart,
            ctrl=jnp.concatenate([arm_q, jnp.full((2,), self.robot.finger_open)]),
            target_velocity=jnp.zeros(self.arm_dof),
            shape=shape,
            size=size,
            colour=jax.random.uniform(colour_key, (n, 3), minval=0.15, maxval=0.95),
            outcome=outcome,
            exit_xy=jnp.zeros((n, 2), jnp.float32),
            target=start.focus.astype(jnp.int32),
            potential=jnp.zeros(len(SHAPING_TERMS), jnp.float32),
            queued_actions=self.initial_action_queue(),
            noise_key=jax.random.fold_in(key, 2),
            # A stream of its own, so every other draw of the episode stays as it was.
            pose_error=jax.random.normal(jax.random.fold_in(key, 3), (n, 3)),
            overflow=jnp.zeros((), jnp.int32),
        )
        model = self.episode_model(sim, params)
        data = self.kinematics(model, sim)
        sim = place_in_hand(ids, self.robot, sim, model, data, start)
        sim = sim.replace(potential=self.shaping_potential(data, sim, params))
        # Moving the focus object to the hand changes no robot quantity, so `data` still serves the observation.
        noise_key, obs_key = jax.random.split(sim.noise_key)
        sim = sim.replace(noise_key=noise_key)
        return sim, self._observe(model, data, sim, params, obs_key), step_info(RewardTerms.zeros(), sim.outcome)

    def _transition(self, sim: PandaSortSim, action: jax.Array, params: PandaSortParams) -> Transition[PandaSortSim]:
        model = self.episode_model(sim, params)
        data = self.kinematics(model, sim)
        applied, queued = delayed_action(sim.queued_actions, action, params.action_latency)
        ctrl, target_velocity = self.limited_ctrl(self._ctrl(model, data, applied, params), sim)
        data = data.replace(ctrl=ctrl)
        data = self.simulate(model, data)
        position = object_positions(self.ids, data.qpos)
        outcome = next_outcome(sim.outcome, sim.shape, position, self.layout)
        leaving = (sim.outcome == IN_PLAY) & (outcome != IN_PLAY)
        qpos, qvel = park(self.ids, data.qpos, data.qvel, outcome != IN_PLAY)
        noise_key, obs_key = jax.random.split(sim.noise_key)
        next_sim = sim.replace(
            qpos=qpos,
            qvel=qvel,
            qacc_warmstart=data.qacc_warmstart,
            ctrl=data.ctrl,
            target_velocity=target_velocity,
            outcome=outcome,
            exit_xy=jnp.where(leaving[:, None], position[:, :2], sim.exit_xy),
            queued_actions=queued,
            noise_key=noise_key,
            overflow=sim.overflow | overflow_bits(data),
        )
        data = self.kinematics(model, next_sim)
        next_sim = next_sim.replace(target=next_target(self.ids, data, next_sim))
        next_sim = next_sim.replace(potential=self.shaping_potential(data, next_sim, params))
        terms = reward_terms(next_sim, sim, params)
        info = step_info(terms, outcome)
        return Transition(
            sim=next_sim,
            obs=self._observe(model, data, next_sim, params, obs_key),
            reward=terms.total(),
            terminated=info.in_play_count == 0,
            success=info.correct_count == self.objects_count,
            info=info,
        )
