"""The Panda's randomisable robot params and the sorter's pose-estimate error: each changes the physics or the
observation as its docstring says, refuses values outside its range, and `randomize` draws it.

The physics rows share one compiled program (`servo_motion`): one env step of the sorter's arm with Franka's
dynamics (the nominal arm has no joint friction to scale), every row's params vmapped together.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from jaxarm import envs
from jaxarm.envs.panda.sim_to_real import with_robot_params
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.panda_sort.env import OBJECT_OBS_SIZE
from jaxarm.envs.panda_sort.objects import pose_index
from jaxarm.envs.peg_insert.env import POSITION_SCALE, PegInsert
from jaxarm.envs.randomize import Randomized, parse_ranges
from tests.envs.compiled import compiled, same_worker

TARGET_OFFSET = 0.3
"""Radians each arm servo's target leads its joint in `servo_motion`: far enough to clamp every servo."""
ROWS = {
    "nominal": {},
    "damped": {"joint_damping_scale": 3.0},
    "sticky": {"joint_friction_scale": 100.0},
    "weak": {"force_limit_scale": 0.5},
    "strong": {"force_limit_scale": 2.0},
    "slow_loop": {"control_period_scale": 1.25},
}
"""The physics rows: params changed from the defaults."""


class ArmState(NamedTuple):
    """What `ArmBase.poses` reads of a sim: qpos [nq], qvel [nv], ctrl [nu], the solver's warm start [nv]."""

    qpos: jax.Array
    qvel: jax.Array
    ctrl: jax.Array
    qacc_warmstart: jax.Array


@pytest.fixture(scope="module")
def franka_sorter() -> PandaSort:
    return PandaSort(dynamics="identified")


@pytest.fixture(scope="module")
def servo_motion(franka_sorter) -> dict[str, np.ndarray]:
    """{row name: [7] each arm joint's travel (radians) in one env step from rest at the start posture, every servo
    target `TARGET_OFFSET` ahead}, under `ROWS`' params."""
    env = franka_sorter
    params = env.default_params()
    rows = [params.replace(**{name: jnp.float32(value) for name, value in row.items()}) for row in ROWS.values()]
    batch = jax.tree.map(lambda *leaves: jnp.stack(leaves), *rows)
    arm = env.ids.robot.arm_qpos
    rest = env.resting(env.start_qpos, 0.04)
    ctrl = jnp.concatenate([env.start_qpos + TARGET_OFFSET, jnp.full(2, 0.04)])
    sim = ArmState(qpos=rest.qpos, qvel=rest.qvel, ctrl=ctrl, qacc_warmstart=rest.qacc_warmstart)

    def travel(row_params):
        model = with_robot_params(env.mjx_model, env.ids.robot, row_params)
        return env.simulate(model, env.poses(model, sim)).qpos[arm] - rest.qpos[arm]

    moved = np.asarray(jax.jit(jax.vmap(travel))(batch))
    return dict(zip(ROWS, moved, strict=True))


@pytest.mark.mjx
def test_tripled_damping_slows_every_joint(servo_motion):
    nominal, damped = servo_motion["nominal"], servo_motion["damped"]
    assert np.all(nominal > 0.002), nominal
    assert np.all(damped < 0.8 * nominal), (damped, nominal)


@pytest.mark.mjx
def test_friction_loss_slows_every_joint_and_nearly_holds_the_wrist(servo_motion):
    # x100 puts 17-27 N·m of Coulomb friction on joints 5-7, more than their servos' 12 N·m; MJX's friction is a soft
    # constraint and the joints' motions couple, so the wrist creeps (a quarter of its nominal travel, measured)
    # rather than sticks.
    nominal, sticky = servo_motion["nominal"], servo_motion["sticky"]
    assert np.all(sticky < 0.9 * nominal), (sticky, nominal)
    assert np.abs(sticky[4:]).sum() < 0.5 * nominal[4:].sum(), (sticky, nominal)


@pytest.mark.mjx
def test_force_limits_bound_how_fast_the_clamped_servos_move_the_arm(servo_motion):
    nominal, weak, strong = servo_motion["nominal"], servo_motion["weak"], servo_motion["strong"]
    # From rest against a clamped force the travel is about proportional to the force limit.
    assert np.all(weak < 0.7 * nominal), (weak, nominal)
    assert np.all(strong > 1.4 * nominal), (strong, nominal)


@pytest.mark.mjx
def test_a_longer_control_period_moves_the_arm_further_per_step(servo_motion):
    nominal, slow = servo_motion["nominal"], servo_motion["slow_loop"]
    assert np.all(slow > 1.2 * nominal), (slow, nominal)


def test_robot_params_reach_the_arm_alone(franka_sorter):
    env = franka_sorter
    model, robot = env.mjx_model, env.ids.robot
    params = env.default_params().replace(
        joint_friction_scale=jnp.float32(2.0),
        force_limit_scale=jnp.float32(0.5),
        control_period_scale=jnp.float32(0.8),
    )
    scaled = with_robot_params(model, robot, params)
    fingers = np.setdiff1d(np.arange(env.mj_model.nu), robot.arm_actuators)
    np.testing.assert_allclose(
        scaled.dof_frictionloss[robot.arm_qpos], 2 * np.asarray(model.dof_frictionloss[robot.arm_qpos])
    )
    np.testing.assert_array_equal(scaled.dof_frictionloss[robot.finger_qpos], model.dof_frictionloss[robot.finger_qpos])
    forcerange = np.asarray(model.actuator_forcerange)
    np.testing.assert_allclose(scaled.actuator_forcerange[robot.arm_actuators], 0.5 * forcerange[robot.arm_actuators])
    np.testing.assert_array_equal(scaled.actuator_forcerange[fingers], forcerange[fingers])
    assert float(scaled.opt.timestep) == pytest.approx(0.8 * float(model.opt.timestep))


def test_finger_pad_scale_resizes_the_pads_alone_about_their_centres(franka_sorter):
    env = franka_sorter
    model, pads = env.mjx_model, env.ids.robot.finger_geoms
    others = np.setdiff1d(np.arange(env.mj_model.ngeom), pads)
    assert [env.mj_model.geom(geom).name for geom in pads] == ["left_pad", "right_pad"]
    default = with_robot_params(model, env.ids.robot, env.default_params())
    for field in ("geom_size", "geom_rbound", "geom_aabb", "geom_pos"):
        np.testing.assert_array_equal(getattr(default, field), getattr(model, field), err_msg=field)
    smaller = with_robot_params(model, env.ids.robot, env.default_params().replace(finger_pad_scale=jnp.float32(0.7)))
    np.testing.assert_allclose(smaller.geom_size[pads], 0.7 * env.mj_model.geom_size[pads], rtol=1e-6)
    np.testing.assert_allclose(smaller.geom_rbound[pads], 0.7 * env.mj_model.geom_rbound[pads], rtol=1e-6)
    # Warp's broadphase culls by the bounding box: a pad's box is its half-sizes about its centre.
    boxes = np.asarray(smaller.geom_aabb).reshape(-1, 2, 3)
    np.testing.assert_allclose(boxes[pads, 1], smaller.geom_size[pads], rtol=1e-6)
    np.testing.assert_array_equal(boxes[pads, 0], np.asarray(model.geom_aabb).reshape(-1, 2, 3)[pads, 0])
    np.testing.assert_array_equal(smaller.geom_pos, model.geom_pos)
    for field in ("geom_size", "geom_rbound"):
        np.testing.assert_array_equal(getattr(smaller, field)[others], getattr(model, field)[others], err_msg=field)


@pytest.mark.mjx
def test_a_smaller_pad_misses_an_object_its_full_size_touches(franka_sorter):
    # An object turned as the left pad and overlapping its edge by 2 mm; MJX's collision of the two.
    env, overlap = franka_sorter, 0.002
    mj_model, pad = env.mj_model, env.ids.robot.finger_geoms[0]
    box = mj_model.geom("object0_box").id
    data = mujoco.MjData(mj_model)
    data.qpos[env.ids.robot.arm_qpos] = env.start_qpos
    mujoco.mj_kinematics(mj_model, data)
    turn = data.geom_xmat[pad].reshape(3, 3)
    reach = mj_model.geom_size[pad, 0] + mj_model.geom_size[box, 0] - overlap
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, data.geom_xmat[pad])
    start = mj_model.jnt_qposadr[mj_model.body_jntadr[mj_model.geom_bodyid[box]]]
    data.qpos[start : start + 7] = [*(data.geom_xpos[pad] + turn[:, 0] * reach), *quat]
    placed = mjx.put_data(mj_model, data)

    @jax.jit
    def depth(scale):
        params = env.default_params().replace(finger_pad_scale=scale)
        model = with_robot_params(env.mjx_model, env.ids.robot, params)
        contact = mjx.collision(model, mjx.kinematics(model, placed))._impl.contact
        pair = jnp.all(jnp.sort(contact.geom, axis=-1) == jnp.sort(jnp.array([pad, box])), axis=-1)
        return jnp.min(jnp.where(pair, contact.dist, jnp.inf))

    assert float(depth(1.0)) == pytest.approx(-overlap, abs=1e-5)
    assert float(depth(0.5)) > 0.0


@pytest.mark.mjx
def test_each_task_steps_and_draws_with_the_params_pads():
    # The sorter's and the peg's episode model, which their physics steps and their cameras draw.
    for env in (PandaSort(), PegInsert()):
        params = env.default_params().replace(finger_pad_scale=jnp.float32(0.5))
        sim = env.reset(jax.random.key(0), params).sim
        pads = env.ids.robot.finger_geoms
        sizes = env.episode_model(sim, params).geom_size[pads]
        np.testing.assert_allclose(sizes, 0.5 * env.mj_model.geom_size[pads], rtol=1e-6, err_msg=type(env).__name__)


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("joint_friction_scale", -0.5, ">= 0"),
        ("force_limit_scale", 0.0, "> 0"),
        ("finger_pad_scale", 0.0, "> 0"),
        ("control_period_scale", 2.0, r"in \[0.5, 1.5\]"),
        ("object_pose_bias", -0.01, ">= 0"),
        ("camera_gray_gain", -0.5, ">= 0"),
        ("camera_depth_noise", -0.001, ">= 0"),
        ("camera_roll", 4.0, r"in \[-3.14159, 3.14159\]"),
    ],
)
def test_values_outside_a_params_range_are_refused(name, value, message):
    params = PandaSort().default_params()
    with pytest.raises(ValueError, match=f"{name}.*{message}"):
        envs.override_params(params, {name: value})


def test_randomize_draws_the_new_params_within_their_ranges():
    ranges = {
        "joint_damping_scale": "log:0.5..4",
        "joint_friction_scale": "0..2",
        "force_limit_scale": "0.7..1.3",
        "control_period_scale": "0.8..1.2",
        "finger_pad_scale": "0.6..1.2",
        "action_latency": "0..2",
        "object_pose_bias": "0..0.01",
        "camera_gray_gain": "0.7..1.3",
        "camera_depth_offset": "-0.02..0.02",
        "camera_shift_z": "-0.006..0.006",
        "camera_pitch": "-0.0436..0.0436",
        "camera_gray_offset": "-0.1..0.1",
        "camera_depth_noise": "0..0.005",
    }
    env = Randomized(PandaSort(), parse_ranges(ranges))
    drawn = jax.vmap(env.episode_params, in_axes=(0, None))(
        jax.random.split(jax.random.key(0), 256), env.default_params()
    )
    for name, text in ranges.items():
        low, high = (float(bound) for bound in text.removeprefix("log:").split(".."))
        values = np.asarray(getattr(drawn, name))
        assert low <= values.min() and values.max() <= high, name
        assert values.std() > 0.1 * (high - low), name
    assert set(np.unique(drawn.action_latency)) == {0, 1, 2}


def test_randomize_refuses_a_control_period_range_beyond_the_params():
    with pytest.raises(ValueError, match=r"randomize.control_period_scale=0.5..2 .*in \[0.5, 1.5\]"):
        Randomized(PandaSort(), parse_ranges({"control_period_scale": "0.5..2"}))


@pytest.mark.mjx
@same_worker("panda_sort")
def test_an_action_reaches_the_servos_two_steps_late():
    sorter = compiled("panda_sort")
    params = sorter.params
    late = envs.override_params(params, {"action_latency": 2})
    action, still = jnp.array([1.0, -1.0, 0.5, 0.5, -1.0]), jnp.zeros(5)
    start = sorter.reset(jax.random.key(4), params)
    delayed, held = start, start
    for _ in range(2):  # the queue starts with zero actions: for two steps the arm does as if told to hold
        delayed, held = sorter.step(delayed, action, late), sorter.step(held, still, params)
        np.testing.assert_array_equal(delayed.sim.qpos, held.sim.qpos)
    prompt = sorter.step(held, action, params)
    np.testing.assert_array_equal(sorter.step(delayed, still, late).sim.qpos, prompt.sim.qpos)


@pytest.mark.mjx
@same_worker("panda_sort")
def test_the_pose_estimate_error_holds_for_the_episode_and_moves_nothing():
    sorter = compiled("panda_sort")
    params = sorter.params
    biased = envs.override_params(params, {"object_pose_bias": 0.01})
    start = sorter.reset(jax.random.key(5), biased)
    np.testing.assert_array_equal(start.sim.qpos, sorter.reset(jax.random.key(5), params).sim.qpos)
    errors, state = [], start
    for action in (jnp.array([1.0, 0.0, -0.5, 0.0, 1.0]), jnp.array([-1.0, 1.0, 0.0, 0.3, -1.0])):
        state = sorter.step(state, action, biased)
        true_position = state.sim.qpos[pose_index(sorter.env.ids)][0, :3]
        errors.append(np.asarray(state.obs[:3] - true_position))
        # The offset to the tool follows the estimate.
        tool = state.obs[OBJECT_OBS_SIZE : OBJECT_OBS_SIZE + 3]
        np.testing.assert_allclose(state.obs[13 + 3 + 1 + 1 : 13 + 3 + 1 + 1 + 3], state.obs[:3] - tool, atol=1e-6)
    np.testing.assert_allclose(errors[0], errors[1], atol=1e-6)
    assert 1e-4 < np.linalg.norm(errors[0]) < 0.05


@pytest.mark.mjx
@same_worker("peg_insert")
def test_the_holes_estimate_error_holds_for_the_episode_and_moves_nothing():
    peg = compiled("peg_insert")
    biased = envs.override_params(peg.params, {"hole_pose_bias": 0.01})
    clean, off = peg.reset(jax.random.key(6), peg.params), peg.reset(jax.random.key(6), biased)
    errors = [np.asarray(off.obs[:3] - clean.obs[:3]) * POSITION_SCALE]
    for action in (jnp.array([1.0, 0.0, -1.0]), jnp.array([0.0, -1.0, 0.5])):
        clean, off = peg.step(clean, action, peg.params), peg.step(off, action, biased)
        np.testing.assert_array_equal(off.sim.qpos, clean.sim.qpos)
        errors.append(np.asarray(off.obs[:3] - clean.obs[:3]) * POSITION_SCALE)
    np.testing.assert_allclose(errors[1:], [errors[0]] * 2, atol=1e-6)
    assert 1e-4 < np.linalg.norm(errors[0]) < 0.05
