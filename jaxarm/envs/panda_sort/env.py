"""The Panda sorter: a Franka Panda puts cubes, cylinders and spheres into the bin of their shape, in MJX.

One env step is `CONTROL_DT` = 0.04 s: the action becomes joint position targets (through damped
least-squares IK in `ee` mode), then MJX takes several physics substeps. An object whose centre enters a bin
(inside its walls, below the rim) is scored: +500 in the bin of its shape, +200 in another. One that drops
below the table top is penalised (-50). Either way it leaves play and is parked far away, at rest, for the
rest of the episode, so it can never be scored twice or touch anything again. The episode terminates when
no object is left in play and succeeds when all of them went into their own bins.

Dense shaping is potential-based: each shaping term pays the change of its potential over the step (reach:
the tool centre near an object; grasp: an object held; lift: a held object lifted; carry: a lifted object
near the point above its own bin), summed over objects, with an object in its own bin counting as the
maximum of every term and one elsewhere as zero. Over an episode the shaping sums to the final potential
minus the first, so no behaviour (hovering with an object over its bin, say) can farm it.

The env holds the mjx.Model (static). Per-episode object shapes and sizes, and the randomised params
(friction, density, mass scale), enter by replacing mjx.Model fields inside the step, so vmap over
states and params is per-env domain randomisation. The sim state keeps only what the physics needs
between steps (qpos, qvel, ctrl, solver warm start), not a whole mjx.Data.
"""

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from mujoco import mjx

from jaxarm.envs.base import Env, EnvSpec, Transition
from jaxarm.envs.panda.robot import (
    FINGER_OPEN,
    HOME_QPOS,
    ik_arm_targets,
    solve_arm_posture,
    tcp_jacobian,
    tcp_pose_at,
)
from jaxarm.envs.panda_sort.layout import Layout, make_layout
from jaxarm.envs.panda_sort.model import ModelIds, build_model, resolve_ids
from jaxarm.envs.panda_sort.params import PandaSortParams, default_params

CONTROL_DT = 0.04
"""Seconds of simulated time per env step."""
MODE_EE = "ee"
MODE_JOINT = "joint"
OBJECT_OBS_SIZE = 26
"""Per object: position 3, quaternion 4, linear and angular velocity 6, one-hot shape 3, size 1, in play 1,
then what a policy would otherwise have to compute: object − tool centre 3, carry target − object 3, and
the object's yaw relative to the hand as cos and sin of 4·Δyaw (a cube and the octagonal cylinder look the
same every 90 degrees)."""
OBJECT_RELATIVE_YAW = slice(OBJECT_OBS_SIZE - 2, OBJECT_OBS_SIZE)
"""Where cos and sin of 4·Δyaw sit in an object's observation."""
START_HEIGHT = 0.25
"""Tool-centre height at reset, pointing down over the middle of the spawn region (the Panda's ready pose is
twice as high, 70 steps of descent away)."""
GRASP_HEIGHT = 0.02
"""Tool-centre height of a grasp-ready start: the pads (24 mm tall) span every object's centre height."""
FLOOR_Z = -0.05
"""An object whose centre is this far below the table top has fallen off."""
TCP_MIN_Z = 0.01
"""Lowest tool-centre target: the arm has no contact with the table, so IK must not drive it through."""
INNER_SCALE = 0.25
"""Size of an object's geoms that do not belong to its shape, per unit size."""
CYLINDER_BOX_HALF = 0.7
"""Half-width of a cylinder's two collision boxes per unit radius: corners at 0.99 r, just inside the circle."""
PARK_ORIGIN = np.array([3.0, 3.0, 1.0], np.float32)
PARK_SPACING = 1.0
"""Out-of-play object k is held at PARK_ORIGIN + k·PARK_SPACING·x, far from everything and from each other."""
HELD_DISTANCE = 0.01
"""An object counts as held when its centre is within its size plus this of the tool centre ..."""
HELD_MIN_SQUEEZE = 0.002
"""... and the fingers are commanded at least this much (metres) closer than they are: they press on something
(open fingers straddling a large object do not hold it) ..."""
HELD_MIN_WIDTH = 1.0
"""... but are open more than this many sizes (fully closed fingers hold nothing; a cylinder is gripped at
1.4 sizes, a small sphere squeezed to about 1.5)."""
GRIP_HALF_WIDTH = np.array([1.0, CYLINDER_BOX_HALF, 1.0], np.float32)
"""Half the finger gap that holds a cube, a cylinder (across the octagon's flats) and a sphere, per unit size."""
PAD_ABOVE_TCP = 0.003
"""The finger pads' centre is this far above the tool centre."""

IN_PLAY = 0
IN_CORRECT_BIN = 1
IN_WRONG_BIN = 2
ON_FLOOR = 3
"""Outcome of an object slot."""


@struct.dataclass
class PandaSortSim:
    """Physics and task state of one env (N = objects_count).

    Attributes:
      qpos: [nq] generalized positions (arm 7, fingers 2, then 7 per object: position, quaternion).
      qvel: [nv] generalized velocities (arm 7, fingers 2, then 6 per object: linear world, angular local).
      qacc_warmstart: [nv] the solver's warm start.
      ctrl: [9] actuator targets (arm joints, then the two fingers).
      shape: [N] int32 SHAPE_* of each object.
      size: [N] half-size / radius of each object (metres).
      colour: [N, 3] RGB of each object; drawn only, never observed, unrelated to the shape.
      outcome: [N] int32 IN_PLAY, IN_CORRECT_BIN, IN_WRONG_BIN or ON_FLOOR.
      target: [] int32 the slot being worked on: the curricula's object at reset; when it leaves play, the
        in-play object nearest the tool centre. Used only by envs built with `target_first`.
      potential: [4] weighted shaping potentials (reach, grasp, lift, carry) of the current state.
    """

    qpos: jax.Array
    qvel: jax.Array
    qacc_warmstart: jax.Array
    ctrl: jax.Array
    shape: jax.Array
    size: jax.Array
    colour: jax.Array
    outcome: jax.Array
    target: jax.Array
    potential: jax.Array


@struct.dataclass
class RewardTerms:
    """The reward of one step, term by term (they sum to `EnvState.reward`)."""

    time: jax.Array
    floor: jax.Array
    wrong_bin: jax.Array
    correct_bin: jax.Array
    reach: jax.Array
    grasp: jax.Array
    lift: jax.Array
    carry: jax.Array

    def total(self) -> jax.Array:
        return sum(jax.tree.leaves(self))


@struct.dataclass
class PandaSortInfo:
    """Per-step diagnostics: the reward terms and this episode's object counts (int32 scalars)."""

    reward_terms: RewardTerms
    correct_count: jax.Array
    wrong_count: jax.Array
    floor_count: jax.Array
    in_play_count: jax.Array


def object_geom_sizes(shape: jax.Array, size: jax.Array) -> jax.Array:
    """[N] shapes, [N] sizes -> [N, 3, 3] geom_size rows of each slot's box, box45 and sphere.

    The drawn shape's geoms get full size; the others INNER_SCALE of it, deep inside where even a finger
    pressing into the soft contact cannot reach them.
    """
    s, half = size[:, None], INNER_SCALE * size[:, None]
    a = CYLINDER_BOX_HALF * s
    zero = jnp.zeros_like(s)
    cube = [jnp.concatenate([s, s, s], -1), jnp.concatenate([half] * 3, -1), jnp.concatenate([half, zero, zero], -1)]
    cylinder = [jnp.concatenate([a, a, s], -1)] * 2 + [jnp.concatenate([half, zero, zero], -1)]
    sphere = [jnp.concatenate([half] * 3, -1)] * 2 + [jnp.concatenate([s, zero, zero], -1)]
    by_shape = jnp.stack([jnp.stack(rows, 1) for rows in (cube, cylinder, sphere)])  # [3, N, 3, 3]
    return jnp.take_along_axis(by_shape, shape[None, :, None, None], axis=0)[0]


def object_mass_inertia(shape: jax.Array, size: jax.Array, density: jax.Array) -> tuple[jax.Array, jax.Array]:
    """[N] shapes and sizes -> mass [N] and principal inertia [N, 3] of solid cubes, cylinders, spheres.

    Cube of half-size s; cylinder of radius s and height 2s; sphere of radius s.
    """
    volume = jnp.stack([8.0 * size**3, 2.0 * jnp.pi * size**3, 4.0 / 3.0 * jnp.pi * size**3])
    mass = density * jnp.take_along_axis(volume, shape[None], axis=0)[0]
    ms2 = (mass * size**2)[:, None]
    cube = jnp.full((3,), 2.0 / 3.0)
    cylinder = jnp.array([7.0 / 12.0, 7.0 / 12.0, 0.5])
    sphere = jnp.full((3,), 0.4)
    factors = jnp.stack([cube, cylinder, sphere])[shape]
    return mass, ms2 * factors


def spawn_xy(
    key: jax.Array, count: int, layout: Layout, max_extent: jax.Array, centre_slot: jax.Array = -1
) -> jax.Array:
    """[count, 2] object positions in distinct cells of the spawn grid, jittered as far as the cell allows.

    `max_extent` bounds every object's horizontal reach from its centre, so objects never overlap. Object
    `centre_slot` (an int, or -1 for none) gets the grid's middle cell (the spawn region's centre lies in it).
    """
    cell_key, jitter_key = jax.random.split(key)
    nx, ny = layout.spawn_cells
    low, high = jnp.array(layout.spawn_low), jnp.array(layout.spawn_high)
    cell = (high - low) / jnp.array([nx, ny])
    order = jax.random.permutation(cell_key, nx * ny)
    middle = (ny // 2) * nx + nx // 2
    at_middle = jnp.argmax(order == middle)
    slot = jnp.maximum(centre_slot, 0)
    swapped = order.at[at_middle].set(order[slot]).at[slot].set(middle)
    chosen = jnp.where(centre_slot >= 0, swapped, order)[:count]
    centre = low + (jnp.stack([chosen % nx, chosen // nx], -1) + 0.5) * cell
    room = jnp.maximum(cell / 2 - max_extent, 0.0)
    return centre + jax.random.uniform(jitter_key, (count, 2), minval=-room, maxval=room)


def yaw_of_rotation(rotation: jax.Array) -> jax.Array:
    """[..., 3, 3] rotation matrices -> [...] heading of their x axis in the horizontal plane (radians)."""
    return jnp.arctan2(rotation[..., 1, 0], rotation[..., 0, 0])


def yaw_of_quaternion(quat: jax.Array) -> jax.Array:
    """[..., 4] unit quaternions (w, x, y, z) -> [...] heading of the rotated x axis (radians)."""
    w, x, y, z = jnp.moveaxis(quat, -1, 0)
    return jnp.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))


def rotation_about_z(angle: jax.Array) -> jax.Array:
    """[] angle -> [3, 3] rotation about the vertical."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(angle), jnp.ones_like(angle)
    return jnp.stack([jnp.stack([c, -s, zero]), jnp.stack([s, c, zero]), jnp.stack([zero, zero, one])])


def bin_membership(position: jax.Array, layout: Layout) -> jax.Array:
    """[N, 3] object positions -> [N, 3] bool: centre inside bin k's walls and below its rim."""
    bins = jnp.array(layout.bin_centers)  # [3, 2]
    inside = jnp.all(jnp.abs(position[:, None, :2] - bins[None]) < layout.bin_half, axis=-1)
    return inside & (position[:, None, 2] < layout.bin_wall_height)


def next_outcome(outcome: jax.Array, shape: jax.Array, position: jax.Array, layout: Layout) -> jax.Array:
    """Scores in-play objects at their new [N, 3] positions; out-of-play outcomes never change."""
    in_bin = bin_membership(position, layout)
    in_own_bin = jnp.take_along_axis(in_bin, shape[:, None], axis=1)[:, 0]
    scored = jnp.select(
        [in_own_bin, jnp.any(in_bin, axis=1), position[:, 2] < FLOOR_Z],
        [IN_CORRECT_BIN, IN_WRONG_BIN, ON_FLOOR],
        IN_PLAY,
    )
    return jnp.where(outcome == IN_PLAY, scored, outcome)


class PandaSort(Env[PandaSortParams, PandaSortSim]):
    """Franka Panda sorting `objects_count` objects into three shape bins.

    Args:
      objects_count: number of object slots, 1 to 5 (static: fixes shapes and the contact set).
      control_mode: "ee" (tool-centre delta xyz, a turn of the hand about the vertical, and a finger command;
        5 actions; the tool keeps pointing down) or "joint" (7 joint-target deltas and a finger command; 8
        actions). The finger command maps [-1, 1] to closed..open.
      blocker: adds a thin bar between the spawn region and the bins.
      tosser: puts the bins on a second table across a gap.
      target_first: one object at a time is the target (`PandaSortSim.target`): the observation lists the
        objects starting from it (slots in cyclic order), and the shaping terms follow it alone, so a policy
        always finds the object to work on in the first slot and several objects become the one-object task
        repeated. With one object nothing changes.
    """

    # jaxlib 0.10.2's CPU runtime deadlocked on this env at 256 envs (one object) and 128 (three): two batched
    # Cholesky factorisations of MJX waited on each other in its two-worker pool (gdb, 2026-11-23).
    cpu_max_envs = 64
    uses_mjx = True

    def __init__(
        self,
        objects_count: int = 1,
        control_mode: str = MODE_EE,
        blocker: bool = False,
        tosser: bool = False,
        target_first: bool = False,
    ):
        if not 1 <= objects_count <= 5:
            raise ValueError(f"objects_count must be in 1..5, got {objects_count}")
        if control_mode not in (MODE_EE, MODE_JOINT):
            raise ValueError(f"control_mode must be {MODE_EE!r} or {MODE_JOINT!r}, got {control_mode!r}")
        self.objects_count = objects_count
        self.control_mode = control_mode
        self.target_first = target_first
        self.layout = make_layout(blocker=blocker, tosser=tosser)
        self.mj_model = build_model(objects_count, self.layout)
        self.ids: ModelIds = resolve_ids(self.mj_model, objects_count)
        self.substeps = int(round(CONTROL_DT / self.mj_model.opt.timestep))
        self.mjx_model = mjx.put_model(self.mj_model)
        self._data0 = mjx.make_data(self.mj_model)
        self._home_tcp_rotation = tcp_pose_at(self.mj_model, self.ids.robot, HOME_QPOS)[1]
        spawn_centre = (np.array(self.layout.spawn_low) + np.array(self.layout.spawn_high)) / 2
        self.start_qpos, self.grasp_qpos = (
            solve_arm_posture(self.mj_model, self.ids.robot, np.r_[spawn_centre, height], self._home_tcp_rotation)
            for height in (START_HEIGHT, GRASP_HEIGHT)
        )
        action_size = 5 if control_mode == MODE_EE else 8
        self.spec = EnvSpec(observation_shape=(OBJECT_OBS_SIZE * objects_count + 21,), action_shape=(action_size,))

    def render(self, state, params: PandaSortParams) -> np.ndarray:
        from jaxarm.envs.panda_sort.render import render_frame

        return render_frame(self, state)

    def default_params(self) -> PandaSortParams:
        return default_params()

    def observation_source_index(self, source) -> np.ndarray:
        """As `Env.observation_source_index`; from a sorter with another object count (same control mode), the
        object rows they share map row to row (with `target_first`, a one-object learner's object becomes the
        target) and the tool's inputs map onto each other; the extra objects' inputs are new (−1)."""
        if not isinstance(source, PandaSort) or source.control_mode != self.control_mode:
            return super().observation_source_index(source)
        shared = min(source.objects_count, self.objects_count)
        objects = np.full((self.objects_count, OBJECT_OBS_SIZE), -1)
        objects[:shared] = np.arange(shared * OBJECT_OBS_SIZE).reshape(shared, OBJECT_OBS_SIZE)
        tool_size = self.spec.observation_size - self.objects_count * OBJECT_OBS_SIZE
        return np.concatenate([objects.ravel(), source.objects_count * OBJECT_OBS_SIZE + np.arange(tool_size)])

    # --- the physics model of one env -------------------------------------------------------------

    def episode_model(self, sim: PandaSortSim, params: PandaSortParams) -> mjx.Model:
        """The mjx.Model with this episode's object shapes and sizes and the params' randomisation."""
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
        return model.replace(
            geom_size=model.geom_size.at[geom_ids].set(sizes),
            geom_rbound=model.geom_rbound.at[geom_ids].set(rbound),
            body_mass=model.body_mass.at[ids.object_body].set(mass),
            body_inertia=model.body_inertia.at[ids.object_body].set(inertia),
            body_invweight0=model.body_invweight0.at[ids.object_body].set(invweight),
            pair_friction=friction,
        )

    def kinematics(self, model: mjx.Model, sim: PandaSortSim) -> mjx.Data:
        """mjx.Data at the sim's state with positions, orientations and com-frame quantities (for Jacobians)."""
        data = self._data0.replace(qpos=sim.qpos, qvel=sim.qvel, ctrl=sim.ctrl, qacc_warmstart=sim.qacc_warmstart)
        return mjx.com_pos(model, mjx.kinematics(model, data))

    # --- control ------------------------------------------------------------------------------------

    def _arm_targets(self, model, data, action, params) -> jax.Array:
        """[7] arm joint targets from the action: IK towards the displaced and turned tool, or joint deltas."""
        robot = self.ids.robot
        if self.control_mode == MODE_JOINT:
            arm_q = data.qpos[robot.arm_qpos]
            return jnp.clip(arm_q + action[:7] * params.joint_step, robot.arm_limits[:, 0], robot.arm_limits[:, 1])
        target = data.site_xpos[robot.tcp_site] + action[:3] * params.ee_step
        target = target.at[2].set(jnp.maximum(target[2], TCP_MIN_Z))
        # The home tool frame has yaw 0, so turning it about z by the target yaw gives a pointing-down target.
        yaw = yaw_of_rotation(data.site_xmat[robot.tcp_site].reshape(3, 3)) + action[3] * params.ee_yaw_step
        rotation = rotation_about_z(yaw) @ self._home_tcp_rotation
        return ik_arm_targets(
            model, data, robot, target, rotation, params.ik_damping, params.ik_posture_gain, self.start_qpos
        )

    def _ctrl(self, model, data, action, params) -> jax.Array:
        finger = (action[-1] + 1.0) * (FINGER_OPEN / 2)
        return jnp.concatenate([self._arm_targets(model, data, action, params), jnp.stack([finger, finger])])

    # --- objects ------------------------------------------------------------------------------------

    def object_positions(self, qpos: jax.Array) -> jax.Array:
        """[nq] -> [N, 3] object centres."""
        return qpos[self.ids.object_qpos[:, None] + np.arange(3)]

    def _park(self, qpos: jax.Array, qvel: jax.Array, outcome: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Holds every out-of-play object at its parking pose, at rest."""
        n = self.objects_count
        park_pos = PARK_ORIGIN + PARK_SPACING * np.arange(n)[:, None] * np.array([1.0, 0.0, 0.0], np.float32)
        park_pose = np.concatenate([park_pos, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))], -1).astype(np.float32)
        out = (outcome != IN_PLAY)[:, None]
        pose_idx = self.ids.object_qpos[:, None] + np.arange(7)
        vel_idx = self.ids.object_qvel[:, None] + np.arange(6)
        qpos = qpos.at[pose_idx].set(jnp.where(out, park_pose, qpos[pose_idx]))
        qvel = qvel.at[vel_idx].set(jnp.where(out, 0.0, qvel[vel_idx]))
        return qpos, qvel

    # --- observation, reward ------------------------------------------------------------------------

    def carry_targets(self, sim: PandaSortSim, params: PandaSortParams) -> jax.Array:
        """[N, 3] the point `carry_height` above the centre of each object's own bin."""
        own_bin = jnp.array(self.layout.bin_centers)[sim.shape]
        return jnp.concatenate([own_bin, jnp.broadcast_to(params.carry_height, (self.objects_count, 1))], -1)

    def _observe(self, model: mjx.Model, data: mjx.Data, sim: PandaSortSim, params: PandaSortParams) -> jax.Array:
        """[OBJECT_OBS_SIZE N + 21]: per object (zeros when out of play) OBJECT_OBS_SIZE values, then tool
        centre position 3, orientation quaternion 4, linear and angular velocity 6, finger width 1, and the 7
        arm joint angles (the arm is redundant, so the tool pose alone does not tell its posture or nearness
        to joint limits). Robot quantities come from `data`, object quantities from `sim`.
        """
        ids = self.ids
        in_play = (sim.outcome == IN_PLAY)[:, None]
        pose = sim.qpos[ids.object_qpos[:, None] + np.arange(7)]
        velocity = sim.qvel[ids.object_qvel[:, None] + np.arange(6)]
        tcp = data.site_xpos[ids.robot.tcp_site]
        relative_yaw = yaw_of_quaternion(pose[:, 3:]) - yaw_of_rotation(
            data.site_xmat[ids.robot.tcp_site].reshape(3, 3)
        )
        objects = jnp.concatenate(
            [
                pose,
                velocity,
                jax.nn.one_hot(sim.shape, 3),
                sim.size[:, None],
                in_play.astype(jnp.float32),
                pose[:, :3] - tcp,
                self.carry_targets(sim, params) - pose[:, :3],
                jnp.cos(4.0 * relative_yaw)[:, None],
                jnp.sin(4.0 * relative_yaw)[:, None],
            ],
            -1,
        )
        tcp_velocity = tcp_jacobian(model, data, ids.robot) @ sim.qvel
        tool = [
            tcp,
            data.xquat[ids.robot.hand_body],
            tcp_velocity,
            jnp.sum(sim.qpos[ids.robot.finger_qpos])[None],
            sim.qpos[ids.robot.arm_qpos],
        ]
        return jnp.concatenate([(objects * in_play)[self.slot_order(sim)].ravel(), *tool]).astype(jnp.float32)

    def slot_order(self, sim: PandaSortSim) -> jax.Array:
        """[N] the object slots in the order the observation lists them: from the target on with
        `target_first`, else as they are."""
        slots = jnp.arange(self.objects_count)
        return (sim.target + slots) % self.objects_count if self.target_first else slots

    def tcp_distances(self, data: mjx.Data, sim: PandaSortSim) -> jax.Array:
        """[N] distance of each object's centre from the tool centre."""
        return jnp.linalg.norm(self.object_positions(sim.qpos) - data.site_xpos[self.ids.robot.tcp_site], axis=-1)

    def next_target(self, data: mjx.Data, sim: PandaSortSim) -> jax.Array:
        """[] int32 the target slot after a step: kept while in play, else the in-play object nearest the tool."""
        in_play = sim.outcome == IN_PLAY
        nearest = jnp.argmin(jnp.where(in_play, self.tcp_distances(data, sim), jnp.inf))
        return jnp.where(in_play[sim.target], sim.target, nearest).astype(jnp.int32)

    def shaping_potential(self, data: mjx.Data, sim: PandaSortSim, params: PandaSortParams) -> jax.Array:
        """[4] weighted potentials (reach, grasp, lift, carry), each summed over objects (see module docstring);
        with `target_first`, in-play objects other than the target count zero."""
        in_play = sim.outcome == IN_PLAY
        position = self.object_positions(sim.qpos)
        distance = self.tcp_distances(data, sim)
        fingers = sim.qpos[self.ids.robot.finger_qpos]
        squeeze = jnp.mean(fingers - sim.ctrl[7:])
        held = (
            (distance < sim.size + HELD_DISTANCE)
            & (squeeze > HELD_MIN_SQUEEZE)
            & (jnp.sum(fingers) > HELD_MIN_WIDTH * sim.size)
        )
        lift = held * jnp.clip((position[:, 2] - sim.size) / params.lift_height, 0.0, 1.0)
        to_target = jnp.linalg.norm(position - self.carry_targets(sim, params), axis=-1)
        stages = jnp.stack(
            [
                1.0 - jnp.tanh(distance / params.reach_scale),
                held.astype(jnp.float32),
                lift,
                lift * (1.0 - jnp.tanh(to_target / params.carry_scale)),
            ]
        )  # [4, N]
        shaped = in_play & (jnp.arange(self.objects_count) == sim.target) if self.target_first else in_play
        per_object = jnp.where(shaped, stages, (sim.outcome == IN_CORRECT_BIN).astype(jnp.float32))
        weights = jnp.stack([params.reach_weight, params.grasp_weight, params.lift_weight, params.carry_weight])
        return weights * jnp.sum(per_object, axis=1)

    def _reward_terms(self, sim: PandaSortSim, previous: PandaSortSim, params: PandaSortParams) -> RewardTerms:
        """Sparse terms for objects scored this step; shaping as the change of each potential."""
        newly = (previous.outcome == IN_PLAY) & (sim.outcome != IN_PLAY)

        def count(outcome: int) -> jax.Array:
            return jnp.sum(newly & (sim.outcome == outcome)).astype(jnp.float32)

        reach, grasp, lift, carry = sim.potential - previous.potential
        return RewardTerms(
            time=params.step_reward,
            floor=params.floor_reward * count(ON_FLOOR),
            wrong_bin=params.wrong_bin_reward * count(IN_WRONG_BIN),
            correct_bin=params.correct_bin_reward * count(IN_CORRECT_BIN),
            reach=reach,
            grasp=grasp,
            lift=lift,
            carry=carry,
        )

    def _info(self, terms: RewardTerms, outcome: jax.Array) -> PandaSortInfo:
        def count(value: int) -> jax.Array:
            return jnp.sum(outcome == value).astype(jnp.int32)

        return PandaSortInfo(
            reward_terms=terms,
            correct_count=count(IN_CORRECT_BIN),
            wrong_count=count(IN_WRONG_BIN),
            floor_count=count(ON_FLOOR),
            in_play_count=count(IN_PLAY),
        )

    # --- the contract -------------------------------------------------------------------------------

    def _reset(self, key, params):
        shape_key, size_key, colour_key, spawn_key, yaw_key, arm_key, start_key = jax.random.split(key, 7)
        # A separate stream for the multi-object curricula, so one-object episodes draw as they always did.
        focus_key, presort_key = jax.random.split(jax.random.fold_in(key, 1))
        n, ids = self.objects_count, self.ids
        # The curricula's object: any slot, so the policy meets held and grasp-ready starts in every input slot.
        focus = jax.random.randint(focus_key, (), 0, n)
        presorted = (jax.random.uniform(presort_key, (n,)) < params.presorted_prob) & (jnp.arange(n) != focus)
        draw, height_draw = jax.random.uniform(start_key, (2,))
        held = draw < params.held_start_prob
        ready = ~held & (draw < params.held_start_prob + params.ready_start_prob)
        # Half the grasp-ready starts hover over the object instead, at a random height: the posture halfway
        # (in joint space) between the low and the start one keeps the tool pointing down within 1.5 cm of the
        # same vertical; from 0.4 of the way up (11 cm, ±1.5 cm of posture noise) the pads clear the tallest object.
        hover = ready & (height_draw >= 0.5)
        blend = jnp.where(hover, 0.4 + 1.2 * (height_draw - 0.5), jnp.where(ready, 0.0, 1.0))
        shape = jax.random.randint(shape_key, (n,), 0, 3).astype(jnp.int32)
        scale = jax.random.uniform(size_key, (n,), minval=params.size_scale_low, maxval=params.size_scale_high)
        size = params.object_size * scale
        xy = spawn_xy(
            spawn_key,
            n,
            self.layout,
            params.object_size * params.size_scale_high * np.sqrt(2.0),
            jnp.where(ready, focus, -1),
        )
        yaw = jax.random.uniform(yaw_key, (n,), maxval=2 * jnp.pi)
        # Resting on the table, 1 mm above it, turned about z.
        zero = jnp.zeros(n)
        pose = jnp.stack([xy[:, 0], xy[:, 1], size + 0.001, jnp.cos(yaw / 2), zero, zero, jnp.sin(yaw / 2)], -1)
        noise = jax.random.uniform(arm_key, (7,), minval=-params.home_noise, maxval=params.home_noise)
        arm_q = (1.0 - blend) * self.grasp_qpos + blend * self.start_qpos + noise
        qpos = self._data0.qpos.at[ids.robot.arm_qpos].set(arm_q).at[ids.robot.finger_qpos].set(FINGER_OPEN)
        qpos = qpos.at[ids.object_qpos[:, None] + np.arange(7)].set(pose)
        outcome = jnp.where(presorted, IN_CORRECT_BIN, IN_PLAY).astype(jnp.int32)
        qpos, qvel = self._park(qpos, jnp.zeros_like(self._data0.qvel), outcome)
        sim = PandaSortSim(
            qpos=qpos,
            qvel=qvel,
            qacc_warmstart=jnp.zeros_like(self._data0.qacc_warmstart),
            ctrl=jnp.concatenate([arm_q, jnp.full((2,), FINGER_OPEN)]),
            shape=shape,
            size=size,
            colour=jax.random.uniform(colour_key, (n, 3), minval=0.15, maxval=0.95),
            outcome=outcome,
            target=focus.astype(jnp.int32),
            potential=jnp.zeros(4, jnp.float32),
        )
        model = self.episode_model(sim, params)
        data = self.kinematics(model, sim)
        sim = self._place_in_hand(sim, data, focus, held, ready, hover)
        sim = sim.replace(potential=self.shaping_potential(data, sim, params))
        zero_terms = RewardTerms(*(jnp.zeros((), jnp.float32) for _ in range(8)))
        # Moving the focus object to the hand changes no robot quantity, so `data` still serves the observation.
        return sim, self._observe(model, data, sim, params), self._info(zero_terms, sim.outcome)

    def _place_in_hand(
        self, sim: PandaSortSim, data: mjx.Data, focus: jax.Array, held: jax.Array, ready: jax.Array, hover: jax.Array
    ) -> PandaSortSim:
        """Curriculum starts for object `focus` (an int32 slot). Where `held`: between the closed fingers at the
        tool centre, faces towards the pads. Where `ready`: on the table under the tool centre, between the
        open fingers (faces towards the pads) or, where also `hover`, below them at the yaw it was drawn with.
        Elsewhere `sim` is returned unchanged."""
        robot = self.ids.robot
        pose_idx = jnp.asarray(self.ids.object_qpos)[focus] + jnp.arange(7)
        own_quat = sim.qpos[pose_idx[3:]]
        yaw = jnp.where(
            hover, yaw_of_quaternion(own_quat), yaw_of_rotation(data.site_xmat[robot.tcp_site].reshape(3, 3))
        )
        tcp = data.site_xpos[robot.tcp_site]
        height = jnp.where(held, tcp[2] + PAD_ABOVE_TCP, sim.size[focus] + 0.001)
        pose = jnp.concatenate([tcp[:2], height[None], jnp.stack([jnp.cos(yaw / 2), 0.0, 0.0, jnp.sin(yaw / 2)])])
        grip = jnp.asarray(GRIP_HALF_WIDTH)[sim.shape[focus]] * sim.size[focus]
        fingers = jnp.where(held, grip, FINGER_OPEN)
        qpos = sim.qpos.at[pose_idx].set(pose).at[robot.finger_qpos].set(fingers)
        ctrl = sim.ctrl.at[7:].set(jnp.where(held, 0.0, FINGER_OPEN))
        moved = held | ready
        return sim.replace(qpos=jnp.where(moved, qpos, sim.qpos), ctrl=jnp.where(moved, ctrl, sim.ctrl))

    def _transition(self, sim, action, params):
        model = self.episode_model(sim, params)
        data = self.kinematics(model, sim)
        data = data.replace(ctrl=self._ctrl(model, data, action, params))
        data = jax.lax.fori_loop(0, self.substeps, lambda _, d: mjx.step(model, d), data)
        outcome = next_outcome(sim.outcome, sim.shape, self.object_positions(data.qpos), self.layout)
        qpos, qvel = self._park(data.qpos, data.qvel, outcome)
        next_sim = sim.replace(
            qpos=qpos, qvel=qvel, qacc_warmstart=data.qacc_warmstart, ctrl=data.ctrl, outcome=outcome
        )
        data = self.kinematics(model, next_sim)
        next_sim = next_sim.replace(target=self.next_target(data, next_sim))
        next_sim = next_sim.replace(potential=self.shaping_potential(data, next_sim, params))
        terms = self._reward_terms(next_sim, sim, params)
        info = self._info(terms, outcome)
        return Transition(
            sim=next_sim,
            obs=self._observe(model, data, next_sim, params),
            reward=terms.total(),
            terminated=info.in_play_count == 0,
            success=info.correct_count == self.objects_count,
            info=info,
        )
