"""Peg-in-hole insertion in MJX: a robot arm (`ArmOptions.robot`, the Panda by default) holds a peg over a block
whose square hole moves every episode.

One env step is `CONTROL_DT` = 0.04 s. The action [3] moves a tool-centre target by at most `ee_step` per
axis; the target is held within `max_lead` of the measured tool centre (so a blocked peg presses with
bounded force) and followed through damped least-squares IK with the tool pointing down (from the measured pose, or
with `running_target` from the servos' targets, as the sorter's), the joints' targets moved within the robot's speed
and acceleration limits (`ArmBase.limited_ctrl`). Reward:
`progress_weight` · (previous − current tip-to-hole-bottom distance) / initial distance, plus
`success_bonus` every step the tip is within `insert_distance` of the hole bottom (inserted, a success).
Terminated when the peg touches the table (its explicit contact pair reports penetration in any substep)
or its tip is further than `max_distance` from the hole bottom; truncated after `max_episode_steps`.

Observation [12], in units that keep it near [-1, 1]: hole bottom − tip (÷ 0.1 m), tip velocity (÷ 0.1 m/s),
tool target − tool centre (÷ max_lead), tip − nominal hole bottom (÷ 0.1 m).

`obs_mode` "pixels" observes {"image": uint8 [R, R, 4]}, grayscale and depth of the fixed scene camera and of
the wrist camera (`ArmBase.camera_image`); "pixels+proprio" adds the arm's own state, {"proprio": [9]}: the
tip velocity, the tool's lead and the tip's offset from the nominal hole; where the hole is this episode shows
only in the images. With `privileged`, a pixel mode's observation also holds the state observation of the same
step ({"privileged": [12]}, for a learner's critic: `jaxarm.envs.observation`).
"""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import mjx

from jaxarm.deploy.camera import LUMA
from jaxarm.envs.base import Observation, Transition
from jaxarm.envs.panda.base import ArmBase, ArmOptions, ArmSim
from jaxarm.envs.panda.dynamics import NOMINAL
from jaxarm.envs.panda.mjx_impl import check_no_overflow, overflow_bits, with_geom_sizes
from jaxarm.envs.panda.robot import advanced_target
from jaxarm.envs.panda.sim_to_real import delayed_action, with_noise, with_robot_params
from jaxarm.envs.peg_insert.model import (
    HOLE_FLOOR,
    HOLE_NOMINAL,
    PEG_LENGTH,
    PEG_RADIUS,
    PegIds,
    build_model,
    hole_walls,
    resolve_ids,
)
from jaxarm.envs.peg_insert.params import PegInsertParams
from jaxarm.envs.peg_insert.render import paint_surfaces, place_block

START_TIP_HEIGHT = 0.15
"""The peg tip starts this high above the table (10 cm above the block), over the nominal hole."""
POSITION_SCALE = 0.1
"""Metres per observation unit of positions and velocities (per second)."""
STATE_OBS_SIZE = 12
"""Values in the state observation (the module docstring lists them)."""


class PegInsertSim(ArmSim):
    """Physics and task state of one env: the robot's share (`ArmSim`; the peg is fixed in the hand, so qpos is the
    arm's and the fingers'), and the peg task's.

    Attributes:
      tcp_target: [3] where the tool centre is being driven.
      hole: [2] (x, y) of the hole's centre this episode.
      initial_distance: [] tip-to-hole-bottom distance at reset (metres).
      distance: [] tip-to-hole-bottom distance after the last step.
      hole_error: [3] the hole's position-estimate error per metre of `hole_pose_bias` (standard normal), drawn at
        reset and kept for the episode.
      surface_gray: [2] the block's and the table's gray this episode (0-1; `surface_gray_spread`).
    """

    tcp_target: jax.Array
    hole: jax.Array
    initial_distance: jax.Array
    distance: jax.Array
    hole_error: jax.Array
    surface_gray: jax.Array


class PegInsertInfo(struct.PyTreeNode):
    """Per-step diagnostics (scalars): the two reward terms, the distance, and why an episode may end."""

    progress: jax.Array
    bonus: jax.Array
    distance: jax.Array
    inserted: jax.Array
    table_contact: jax.Array


class PegInsert(ArmBase[PegInsertParams, PegInsertSim, PegIds]):
    """A robot arm inserting a peg held in its hand into a square hole shifted at random every episode.

    Args:
      dynamics: the robot's link inertials and joint friction: "nominal" (its model file's) or "identified" (its
        description's identified links, the Panda's from Franka's published values: `jaxarm.envs.panda.dynamics`).
      running_target: the IK starts from the servos' targets instead of the measured pose, and the target the
        servos chase is the tool centre at those targets, moved by the action (`_arm_targets`), as the sorter's
        `running_target`. Without it (the default) the IK starts from the measured pose.
      options: the physics, its buffers and the observation (`ArmOptions`; the module docstring says what each
        observation mode holds).
    """

    def __init__(self, dynamics: str = NOMINAL, running_target: bool = False, *, options: ArmOptions = ArmOptions()):
        self.running_target = running_target
        mj_model = build_model(dynamics=dynamics, robot=options.robot)
        start_tcp = np.array([*HOLE_NOMINAL, START_TIP_HEIGHT + PEG_LENGTH])
        super().__init__(mj_model, resolve_ids(mj_model, options.robot), start_tcp, options)
        self.spec = self.observation_spec(STATE_OBS_SIZE, 9, 3)

    def default_params(self) -> PegInsertParams:
        return PegInsertParams()

    # --- physics ------------------------------------------------------------------------------------

    def episode_model(self, sim: PegInsertSim, params: PegInsertParams) -> mjx.Model:
        """The mjx.Model with this episode's hole position and the params' clearance, friction and robot params."""
        ids = self.ids
        model = with_robot_params(self.mjx_model, ids.robot, params)
        centres, halves = hole_walls(params.clearance)
        block_pos = jnp.concatenate([sim.hole, jnp.zeros(1)])
        model = with_geom_sizes(model, ids.wall_geoms, halves, jnp.linalg.norm(halves, axis=-1))
        return model.replace(
            body_pos=model.body_pos.at[ids.block_body].set(block_pos),
            geom_pos=model.geom_pos.at[ids.wall_geoms].set(centres),
            pair_friction=model.pair_friction.at[ids.block_pairs, :2].set(params.friction),
        )

    def _pose_for_drawing(self, model: mujoco.MjModel, sim: PegInsertSim, params: PegInsertParams) -> None:
        place_block(model, self.ids, np.asarray(sim.hole), np.asarray(params.clearance))
        paint_surfaces(model, self.ids, np.asarray(sim.surface_gray))

    def surface_gray(self, key: jax.Array, params: PegInsertParams) -> jax.Array:
        """[2] the block's and the table's gray of an episode drawn from `key`: each its modelled gray (`mj_model`'s
        rgba luma) moved by U(−`surface_gray_spread`, spread), within 0-1."""
        modelled = self.mj_model.geom_rgba[[self.ids.block_geoms[0], self.ids.table_geom], :3] @ LUMA
        shift = jax.random.uniform(key, (2,), minval=-1.0, maxval=1.0) * params.surface_gray_spread
        return jnp.clip(modelled + shift, 0.0, 1.0)

    def episode_luma(self, sim: PegInsertSim) -> jax.Array:
        """The cameras' brightness of each geom with the block's and the table's this episode's (`sim.surface_gray`)."""
        scene = self.camera_scene
        block = np.isin(scene.geoms, self.ids.block_geoms)
        table = scene.geoms == self.ids.table_geom
        return jnp.where(block, sim.surface_gray[0], jnp.where(table, sim.surface_gray[1], scene.luma))

    def table_contact(self, data: mjx.Data) -> jax.Array:
        """[] bool: the peg penetrates the table top in the last collision pass (whose poses `data` holds).

        The table-peg pair is plane-capsule, whose contact distances are the heights of the capsule's end
        spheres over the plane; they are computed here because Warp's contacts of a whole batch share one
        buffer that no env can pick its own from.
        """
        ids = self.ids
        radius, half_length = self.mj_model.geom_size[ids.peg_geom, :2]
        axis = data.geom_xmat[ids.peg_geom][:, 2]
        ends = data.geom_xpos[ids.peg_geom] + jnp.array([[half_length], [-half_length]]) * axis
        heights = (ends - data.geom_xpos[ids.table_geom]) @ data.geom_xmat[ids.table_geom][:, 2] - radius
        return jnp.any(heights < 0.0)

    def peg_tip(self, data: mjx.Data) -> jax.Array:
        return data.site_xpos[self.ids.peg_tip]

    @staticmethod
    def hole_bottom(sim: PegInsertSim) -> jax.Array:
        return jnp.concatenate([sim.hole, jnp.full((1,), HOLE_FLOOR)])

    # --- observation --------------------------------------------------------------------------------

    def _observe(
        self, model: mjx.Model, data: mjx.Data, sim: PegInsertSim, params: PegInsertParams, key: jax.Array
    ) -> Observation:
        """The observation (the module docstring says what each mode holds); `key` draws the params' noise on the
        tip's position and velocity and on the hole's position (beside the episode's error in estimating it)."""
        tip_key, velocity_key, hole_key = jax.random.split(key, 3)
        exact_tip = self.peg_tip(data)
        jacp, _ = mjx.jac(model, data, exact_tip, self.ids.robot.hand_body)
        tip = with_noise(exact_tip, tip_key, params.obs_noise)
        tip_velocity = with_noise(jacp.T @ sim.qvel, velocity_key, params.obs_noise)
        estimate = self.hole_bottom(sim) + params.hole_pose_bias * sim.hole_error
        hole_bottom = with_noise(estimate, hole_key, params.hole_pose_noise)
        nominal = jnp.array([*HOLE_NOMINAL, HOLE_FLOOR])
        lead = (sim.tcp_target - data.site_xpos[self.ids.robot.tcp_site]) / params.max_lead
        state = jnp.concatenate(
            [
                (hole_bottom - tip) / POSITION_SCALE,
                tip_velocity / POSITION_SCALE,
                lead,
                (tip - nominal) / POSITION_SCALE,
            ]
        ).astype(jnp.float32)
        proprio = jnp.concatenate([tip_velocity / POSITION_SCALE, lead, (tip - nominal) / POSITION_SCALE])
        return self.observation(state, proprio)

    # --- the contract -------------------------------------------------------------------------------

    def _reset(self, key, params):
        hole_key, arm_key = jax.random.split(key)
        hole = jnp.array(HOLE_NOMINAL) + jax.random.uniform(hole_key, (2,), minval=-1.0, maxval=1.0) * params.hole_shift
        robot = self.ids.robot
        arm_q = self.start_qpos + jax.random.uniform(
            arm_key, (self.arm_dof,), minval=-params.home_noise, maxval=params.home_noise
        )
        fingers = jnp.full((2,), PEG_RADIUS)
        resting = self.resting(arm_q, fingers)
        zero = jnp.zeros((), jnp.float32)
        sim = PegInsertSim(
            qpos=resting.qpos,
            qvel=resting.qvel,
            qacc_warmstart=resting.qacc_warmstart,
            ctrl=jnp.concatenate([arm_q, fingers]),
            target_velocity=jnp.zeros(self.arm_dof),
            tcp_target=jnp.zeros(3),
            hole=hole,
            initial_distance=zero,
            distance=zero,
            queued_actions=self.initial_action_queue(),
            noise_key=jax.random.fold_in(key, 2),
            # A stream of its own, so every other draw of the episode stays as it was.
            hole_error=jax.random.normal(jax.random.fold_in(key, 3), (3,)),
            surface_gray=self.surface_gray(jax.random.fold_in(key, 4), params),
            overflow=jnp.zeros((), jnp.int32),
        )
        model = self.episode_model(sim, params)
        data = self.kinematics(model, sim)
        distance = jnp.linalg.norm(self.peg_tip(data) - self.hole_bottom(sim))
        sim = sim.replace(tcp_target=data.site_xpos[robot.tcp_site], initial_distance=distance, distance=distance)
        info = PegInsertInfo(
            progress=zero,
            bonus=zero,
            distance=distance,
            inserted=jnp.zeros((), jnp.bool_),
            table_contact=jnp.zeros((), jnp.bool_),
        )
        noise_key, obs_key = jax.random.split(sim.noise_key)
        return sim.replace(noise_key=noise_key), self._observe(model, data, sim, params, obs_key), info

    def _arm_targets(
        self, model: mjx.Model, data: mjx.Data, sim: PegInsertSim, action: jax.Array, params: PegInsertParams
    ) -> tuple[jax.Array, jax.Array]:
        """The applied `action` [3] -> (the next tool-centre target [3], the arm's joint targets [J]): the target
        the servos chase (`sim.tcp_target`, or with `running_target` the tool centre at the servos' targets) moved
        by the action, held within `max_lead` of the measured tool centre (`data`'s), and IK towards it from the
        measured pose, or with `running_target` from the servos' targets (`ArmBase.servo_ik_targets`)."""
        tcp = data.site_xpos[self.ids.robot.tcp_site]
        step = action * params.ee_step
        if self.running_target:
            servo_data = self.at_servo_targets(model, data)
            target = advanced_target(servo_data.site_xpos[self.ids.robot.tcp_site], step, tcp, params.max_lead)
            return target, self.servo_ik_targets(model, servo_data, target, self.home_tcp_rotation, params)
        target = advanced_target(sim.tcp_target, step, tcp, params.max_lead)
        return target, self.ik_targets(model, data, target, self.home_tcp_rotation, params)

    def _transition(self, sim, action, params):
        model = self.episode_model(sim, params)
        data = self.kinematics(model, sim)
        applied, queued = delayed_action(sim.queued_actions, action, params.action_latency)
        target, arm_ctrl = self._arm_targets(model, data, sim, applied, params)
        ctrl, target_velocity = self.limited_ctrl(jnp.concatenate([arm_ctrl, sim.ctrl[self.arm_dof :]]), sim)
        data = data.replace(ctrl=ctrl)

        def substep(_, carry):
            data, touched = carry
            data = mjx.step(model, data)
            return data, touched | self.table_contact(data)

        data, touched = jax.lax.fori_loop(0, self.substeps, substep, (data, jnp.zeros((), jnp.bool_)))
        data = check_no_overflow(data)
        noise_key, obs_key = jax.random.split(sim.noise_key)
        next_sim = sim.replace(
            qpos=data.qpos,
            qvel=data.qvel,
            qacc_warmstart=data.qacc_warmstart,
            ctrl=data.ctrl,
            target_velocity=target_velocity,
            tcp_target=target,
            queued_actions=queued,
            noise_key=noise_key,
            overflow=sim.overflow | overflow_bits(data),
        )
        data = self.kinematics(model, next_sim)
        distance = jnp.linalg.norm(self.peg_tip(data) - self.hole_bottom(next_sim))
        next_sim = next_sim.replace(distance=distance)
        inserted = distance < params.insert_distance
        progress = params.progress_weight * (sim.distance - distance) / sim.initial_distance
        bonus = params.success_bonus * inserted
        info = PegInsertInfo(
            progress=progress, bonus=bonus, distance=distance, inserted=inserted, table_contact=touched
        )
        return Transition(
            sim=next_sim,
            obs=self._observe(model, data, next_sim, params, obs_key),
            reward=progress + bonus,
            terminated=touched | (distance > params.max_distance),
            success=inserted,
            info=info,
        )
