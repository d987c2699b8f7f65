"""The sorter's training start states (curricula), drawn per episode at reset; evaluation uses none of them.

With the params' probabilities an episode starts with its focus object (any slot) held between the closed
fingers, or grasp-ready: on the table right under the tool, between the open fingers of the lowered arm, or
(half of those) below them at a random height. A held start may begin wound up to throw (the tosser): the arm
at the scripted throw's wind-up posture, facing the held object's bin, or somewhere on the way there.
Independently, each other object may start presorted: in its own bin, out of play. Everything else starts as a
plain episode: every object on the table, the arm raised.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from mujoco import mjx
from mujoco.mjx._src import math as mjx_math

from jaxarm.envs.panda.robot import yaw_of_quaternion, yaw_of_rotation
from jaxarm.envs.panda_sort.model import ModelIds
from jaxarm.envs.panda_sort.objects import GRIP_HALF_WIDTH
from jaxarm.envs.panda_sort.params import PandaSortParams
from jaxarm.envs.panda_sort.sim import PandaSortSim
from jaxarm.robots import RobotDescription

WIND_UP_POSTURE = np.array([0.0, -1.5, 0.0, -0.35, 0.0, 3.4, -0.785], np.float32)
"""Joints 2-7 of the throw's wind-up (joint 1 faces the bin): upper arm leaning back, hand raised behind, the
pads facing along the swing (scripted_throw.py). Turned a quarter the other way, pitching the hand about the
pads' normal let the object slide out at once."""
FLIP_ABOUT_X = np.array([0.0, 1.0, 0.0, 0.0], np.float32)
"""Half a turn about x (w, x, y, z), from the tool centre's frame to a held object's: the tool's z axis points out
of the hand, the object's up into it."""


def wound_up_posture(bin_xy: jax.Array) -> jax.Array:
    """[2] a bin's centre -> [7] the wind-up posture with the base turned to face it."""
    return jnp.asarray(WIND_UP_POSTURE).at[0].set(jnp.arctan2(bin_xy[1], bin_xy[0]))


class StartDraw(NamedTuple):
    """The curricula's choices for one episode.

    Attributes:
      focus: [] int32 the slot of the curricula's object.
      presorted: [N] bool, the object starts in its own bin (never the focus object).
      held: [] bool, the focus object starts between the closed fingers.
      ready: [] bool, the focus object starts under the open fingers (grasp-ready, or hovering below them).
      hover: [] bool, a grasp-ready start with the hand raised over the object.
      wound_up: [] bool, a held start with the arm wound up to throw.
      wind_up: [] how far a wound-up start's arm is from the held start's posture (0) to the wind-up (1).
      blend: [] where the arm starts between the grasp posture (0) and the start posture (1), in joint space.
    """

    focus: jax.Array
    presorted: jax.Array
    held: jax.Array
    ready: jax.Array
    hover: jax.Array
    wound_up: jax.Array
    wind_up: jax.Array
    blend: jax.Array


def draw_start(start_key: jax.Array, objects_key: jax.Array, objects_count: int, params: PandaSortParams) -> StartDraw:
    """Draws the episode's start: the hand's from `start_key`, the focus slot and the presorted objects from
    `objects_key`."""
    focus_key, presort_key = jax.random.split(objects_key)
    # The curricula's object: any slot, so the policy meets held and grasp-ready starts in every input slot.
    focus = jax.random.randint(focus_key, (), 0, objects_count)
    others = jnp.arange(objects_count) != focus
    presorted = (jax.random.uniform(presort_key, (objects_count,)) < params.presorted_prob) & others
    draw, height_draw = jax.random.uniform(start_key, (2,))
    held = draw < params.held_start_prob
    ready = ~held & (draw < params.held_start_prob + params.ready_start_prob)
    # Half the grasp-ready starts hover over the object instead, at a random height: the posture halfway
    # (in joint space) between the low and the start one keeps the tool pointing down within 1.5 cm of the
    # same vertical; from 0.4 of the way up (11 cm, ±1.5 cm of posture noise) the pads clear the tallest object.
    hover = ready & (height_draw >= 0.5)
    # A key of its own, so that the other starts draw as they did before the wind-up existed.
    wound_up = held & (jax.random.uniform(jax.random.fold_in(start_key, 1)) < params.wind_up_start_prob)
    wind_up = 1.0 - params.wind_up_spread * jax.random.uniform(jax.random.fold_in(start_key, 2))
    blend = jnp.where(hover, 0.4 + 1.2 * (height_draw - 0.5), jnp.where(ready, 0.0, 1.0))
    return StartDraw(
        focus=focus,
        presorted=presorted,
        held=held,
        ready=ready,
        hover=hover,
        wound_up=wound_up,
        wind_up=wind_up,
        blend=blend,
    )


def pose_in_hand(ids: ModelIds, robot: RobotDescription, model: mjx.Model, data: mjx.Data) -> jax.Array:
    """[7] pose of an object held between the pads, whatever the hand's orientation: centred between them,
    its z axis against the tool centre's (so upright when the tool points down), in `robot`'s hand."""
    tcp_site = ids.robot.tcp_site
    z_axis = data.site_xmat[tcp_site].reshape(3, 3)[:, 2]
    site_quat = mjx_math.quat_mul(data.xquat[model.site_bodyid[tcp_site]], model.site_quat[tcp_site])
    centre = data.site_xpos[tcp_site] - robot.pad_above_tcp * z_axis
    return jnp.concatenate([centre, mjx_math.quat_mul(site_quat, jnp.asarray(FLIP_ABOUT_X))])


def place_in_hand(
    ids: ModelIds, robot: RobotDescription, sim: PandaSortSim, model: mjx.Model, data: mjx.Data, start: StartDraw
) -> PandaSortSim:
    """Curriculum starts for the `start.focus` object in `robot`'s hand, with `data` the kinematics of `sim`. Where
    `start.held`:
    between the closed fingers at the tool centre, faces towards the pads (upright, or where `start.wound_up` in
    the hand's frame). Where `start.ready`: on the table under the tool centre, between the open fingers (faces
    towards the pads) or, where also `start.hover`, below them at the yaw it was drawn with. Elsewhere `sim` is
    returned unchanged."""
    robot_ids = ids.robot
    focus, held = start.focus, start.held
    pose_idx = jnp.asarray(ids.object_qpos)[focus] + jnp.arange(7)
    own_quat = sim.qpos[pose_idx[3:]]
    yaw = jnp.where(
        start.hover, yaw_of_quaternion(own_quat), yaw_of_rotation(data.site_xmat[robot_ids.tcp_site].reshape(3, 3))
    )
    tcp = data.site_xpos[robot_ids.tcp_site]
    height = jnp.where(held, tcp[2] + robot.pad_above_tcp, sim.size[focus] + 0.001)
    pose = jnp.concatenate([tcp[:2], height[None], jnp.stack([jnp.cos(yaw / 2), 0.0, 0.0, jnp.sin(yaw / 2)])])
    pose = jnp.where(start.wound_up, pose_in_hand(ids, robot, model, data), pose)
    grip = jnp.asarray(GRIP_HALF_WIDTH)[sim.shape[focus]] * sim.size[focus]
    fingers = jnp.where(held, grip, robot.finger_open)
    qpos = sim.qpos.at[pose_idx].set(pose).at[robot_ids.finger_qpos].set(fingers)
    ctrl = sim.ctrl.at[len(robot.arm_joints) :].set(jnp.where(held, 0.0, robot.finger_open))
    moved = held | start.ready
    return sim.replace(qpos=jnp.where(moved, qpos, sim.qpos), ctrl=jnp.where(moved, ctrl, sim.ctrl))
