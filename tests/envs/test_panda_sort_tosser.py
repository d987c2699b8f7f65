"""The tosser (`panda_sort_tosser`): its bins stand beyond anything the arm can reach, and an object thrown with
the right ballistic velocity lands in the aimed bin and scores as in the sorter."""

import functools
import itertools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxarm import deployable
from jaxarm.deploy import scoring
from jaxarm.deployable import panda_sort
from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.panda_sort import MODE_JOINT, SHAPE_CUBE, SHAPE_SPHERE, PandaSort
from jaxarm.envs.panda_sort.curriculum import wound_up_posture
from jaxarm.envs.panda_sort.reward import FLOOR_Z, SHAPING_TERMS
from jaxarm.envs.panda_sort.scripted_throw import aimed_throw, throw_action
from jaxarm.robots import PANDA
from tests.deploy.test_scoring import scoring_state
from tests.envs.compiled import compiled, same_worker
from tests.envs.test_panda_sort import shaping_potential, with_object

pytestmark = same_worker("panda_sort_tosser")

REACH_SAMPLES = 20_000
GRAVITY = 9.81
TOSS_WEIGHT = 10.0


def wall_distances(layout) -> np.ndarray:
    """Horizontal distance from the robot's base (the origin) to the nearest point of each bin wall."""
    nearest = []
    for wall in layout.bin_walls:
        centre, half = np.array(wall.center[:2]), np.array(wall.half[:2])
        nearest.append(np.linalg.norm(np.maximum(np.abs(centre) - half, 0.0)))
    return np.array(nearest)


def test_no_pose_of_the_arm_reaches_a_bin():
    env = compiled("panda_sort_tosser").env
    model, robot = env.mj_model, env.ids.robot
    data = mujoco.MjData(model)
    robot_geoms = [
        g for g in range(model.ngeom) if model.body_rootid[model.geom_bodyid[g]] == model.body_rootid[robot.hand_body]
    ]
    rng = np.random.default_rng(0)
    tool_reach = farthest = 0.0
    for _ in range(REACH_SAMPLES):
        data.qpos[robot.arm_qpos] = rng.uniform(robot.arm_limits[:, 0], robot.arm_limits[:, 1])
        mujoco.mj_kinematics(model, data)
        tcp = data.site_xpos[robot.tcp_site]
        if abs(tcp[2]) < 0.1:
            tool_reach = max(tool_reach, float(np.hypot(*tcp[:2])))
        extents = np.hypot(*data.geom_xpos[robot_geoms, :2].T) + model.geom_rbound[robot_geoms]
        farthest = max(farthest, float(extents.max()))
    nearest_wall = wall_distances(env.layout).min()
    assert tool_reach > 0.85, "the sampling found the Panda's reach"
    assert nearest_wall >= tool_reach + 0.3
    assert farthest < nearest_wall, "no part of the arm (bounding spheres) reaches a bin wall"


def test_the_video_camera_frames_the_arm_wound_up_and_every_bin():
    """The `front` camera of a 320x240 video holds each bin, the robot's base and the hand wound up to throw."""
    env = compiled("panda_sort_tosser").env
    model, robot = env.mj_model, env.ids.robot
    data = mujoco.MjData(model)
    data.qpos[robot.arm_qpos] = np.asarray(wound_up_posture(jnp.asarray(env.layout.bin_centers[1])))
    mujoco.mj_forward(model, data)
    points = [[x, y, env.layout.bin_wall_height] for x, y in env.layout.bin_centers]
    points += [[0.0, 0.0, 0.0], data.site_xpos[robot.tcp_site]]
    camera = model.camera("front").id
    # Camera frame: x right, y up, looking along -z.
    seen = (np.array(points) - data.cam_xpos[camera]) @ data.cam_xmat[camera].reshape(3, 3)
    half_height = np.tan(np.radians(model.cam_fovy[camera]) / 2)
    assert np.all(seen[:, 2] < 0)
    image = seen[:, :2] / -seen[:, 2:]
    assert np.all(np.abs(image[:, 0]) < 0.95 * half_height * 320 / 240), image
    assert np.all(np.abs(image[:, 1]) < 0.95 * half_height), image


RELEASE = np.array([0.4, 0.6, 0.35])
"""Where these tests' throws let go: beyond the near table's edge."""


def ballistic_velocity(start: np.ndarray, target: np.ndarray, flight_s: float) -> np.ndarray:
    """[3] launch velocity carrying a point from `start` to `target` in `flight_s` seconds under gravity alone."""
    return (target - start) / flight_s + np.array([0.0, 0.0, GRAVITY * flight_s / 2])


@pytest.mark.mjx
@pytest.mark.parametrize(
    ("shape", "aimed", "reward"), [(SHAPE_CUBE, SHAPE_CUBE, 500.0), (SHAPE_SPHERE, SHAPE_CUBE, 200.0)]
)
def test_a_thrown_object_lands_in_the_aimed_bin_and_scores(shape, aimed, reward):
    shared = compiled("panda_sort_tosser")
    env, params = shared.env, shared.params
    size = 0.025
    target = np.array([*env.layout.bin_centers[aimed], size])
    velocity = ballistic_velocity(RELEASE, target, flight_s=0.6)
    state = shared.reset(jax.random.key(0), params)
    state = with_object(env, state, shape, size, [*RELEASE, 1, 0, 0, 0], [*velocity, 0, 0, 0])
    # The toss potential of the object in flight, by hand: 1 − tanh(d / toss_scale), d to its own bin's centre.
    params = params.replace(toss_weight=jnp.float32(TOSS_WEIGHT))
    own_bin = np.array(env.layout.bin_centers[shape])
    toss = TOSS_WEIGHT * (1 - np.tanh(np.linalg.norm(RELEASE[:2] - own_bin) / float(params.toss_scale)))
    state = state.replace(sim=state.sim.replace(potential=jnp.asarray(shaping_potential(env, state, params))))
    np.testing.assert_allclose(float(state.sim.potential[SHAPING_TERMS.index("toss")]), toss, rtol=1e-5)
    rewards, tosses = [], []
    for _ in itertools.repeat(None, 30):  # 1.2 s: the flight and then some
        state = shared.step(state, jnp.zeros(env.spec.action_shape), params)
        terms = state.info.reward_terms
        rewards.append((float(terms.correct_bin), float(terms.wrong_bin), float(terms.floor)))
        tosses.append(float(terms.toss))
    scored = [value for step in rewards for value in step if value != 0]
    assert scored == [reward], rewards
    landed = next(t for t, step in enumerate(rewards) if any(step))
    if shape == aimed:
        # Flying towards its own bin the object earns toss shaping every step, and in the bin the full weight.
        assert min(tosses[:landed]) > 0, tosses
        np.testing.assert_allclose(sum(tosses), TOSS_WEIGHT - toss, atol=1e-3)
    else:
        # Landing in another bin hands back what the toss term paid (it counts zero there).
        np.testing.assert_allclose(sum(tosses), -toss, atol=1e-3)


SHORT = np.array([0.36, 0.95, -0.3])
"""A point on the floor between the tables, short of every bin."""


def let_go_towards_short(shared, params):
    """A cube let go at RELEASE on its way to SHORT (0.5 s of flight): (the state, its shaping potential under
    `params` stored; [3] the velocity)."""
    velocity = ballistic_velocity(RELEASE, SHORT, flight_s=0.5)
    state = shared.reset(jax.random.key(0), params)
    state = with_object(shared.env, state, SHAPE_CUBE, 0.025, [*RELEASE, 1, 0, 0, 0], [*velocity, 0, 0, 0])
    potential = jnp.asarray(shaping_potential(shared.env, state, params))
    return state.replace(sim=state.sim.replace(potential=potential)), velocity


def floor_crossing(velocity: np.ndarray) -> np.ndarray:
    """[2] where the path from RELEASE at `velocity` drops below the floor line (`FLOOR_Z`)."""
    crossing_s = max(np.roots([-GRAVITY / 2, velocity[2], RELEASE[2] - FLOOR_Z]))
    return RELEASE[:2] + velocity[:2] * crossing_s


def fly(shared, state, params):
    """30 steps of zero actions (1.2 s): (the last state, [30] toss terms, [30] floor terms)."""
    tosses, floors = [], []
    for _ in itertools.repeat(None, 30):
        state = shared.step(state, jnp.zeros(shared.env.spec.action_shape), params)
        tosses.append(float(state.info.reward_terms.toss))
        floors.append(float(state.info.reward_terms.floor))
    return state, tosses, floors


@pytest.mark.mjx
def test_a_throw_that_falls_short_keeps_the_toss_potential_of_where_it_fell():
    shared = compiled("panda_sort_tosser")
    env, params = shared.env, shared.params.replace(toss_weight=jnp.float32(TOSS_WEIGHT))
    state, velocity = let_go_towards_short(shared, params)
    toss_index = SHAPING_TERMS.index("toss")
    released = float(state.sim.potential[toss_index])
    state, tosses, floors = fly(shared, state, params)
    assert [value for value in floors if value] == [-50.0]
    # It left play where it dropped below the table top: on its flight path, within a step's travel of the
    # point where the path crosses that height.
    crossing = floor_crossing(velocity)
    fell = np.asarray(state.sim.exit_xy[0])
    assert np.linalg.norm(fell - crossing) < np.linalg.norm(velocity[:2]) * CONTROL_DT, (fell, crossing)
    # On the floor it keeps the toss potential of that spot, by hand, and the toss terms telescope to it.
    own_bin = np.array(env.layout.bin_centers[SHAPE_CUBE])
    kept = TOSS_WEIGHT * (1 - np.tanh(np.linalg.norm(fell - own_bin) / float(params.toss_scale)))
    assert kept > 0.1 * TOSS_WEIGHT
    np.testing.assert_allclose(float(state.sim.potential[toss_index]), kept, rtol=1e-5)
    np.testing.assert_allclose(sum(tosses), kept - released, atol=1e-3)


@pytest.mark.mjx
def test_with_toss_flight_an_object_in_flight_counts_where_it_will_fall():
    """At `toss_flight` 1 the toss term places an object let go in flight where its path drops below the floor
    line: by hand at the release, in the env and in the deployment package's numpy scoring; over the flight the
    term then pays no more than a step's travel is worth, where at 0 it pays the whole way (the test above)."""
    shared = compiled("panda_sort_tosser")
    env = shared.env
    assert tuple(env.mj_model.opt.gravity) == (0.0, 0.0, -scoring.GRAVITY)
    params = shared.params.replace(toss_weight=jnp.float32(TOSS_WEIGHT), toss_flight=jnp.float32(1.0))
    toss_scale = float(params.toss_scale)
    state, velocity = let_go_towards_short(shared, params)
    potential = np.asarray(state.sim.potential)
    own_bin = np.array(env.layout.bin_centers[SHAPE_CUBE])
    by_hand = TOSS_WEIGHT * (1 - np.tanh(np.linalg.norm(floor_crossing(velocity) - own_bin) / toss_scale))
    # Where it is it would count far less: the flight carries it most of the way towards the bin.
    assert by_hand > 2 * TOSS_WEIGHT * (1 - np.tanh(np.linalg.norm(RELEASE[:2] - own_bin) / toss_scale))
    np.testing.assert_allclose(potential[SHAPING_TERMS.index("toss")], by_hand, rtol=1e-5)
    controller = deployable.controller(env, params)
    seen = scoring_state(env, controller, state.sim, int(state.sim.target))
    ours = scoring.shaping_potential(seen, controller.task.bins, panda_sort.sort_reward(env, params))
    np.testing.assert_allclose(ours, potential, rtol=1e-4, atol=1e-4)
    state, tosses, _ = fly(shared, state, params)
    assert int(state.sim.outcome[0]) == scoring.ON_FLOOR
    # The term is 1/toss_scale-Lipschitz in the distance: what the flight pays is bounded by the gap between the
    # step it fell in and the crossing (test above).
    step_travel = np.linalg.norm(velocity[:2]) * CONTROL_DT
    assert abs(sum(tosses)) <= TOSS_WEIGHT * step_travel / toss_scale, tosses


THROW_STEPS = 110
STARTS = 8
SWING_START = 70  # two steps after the wind-up ends
RELEASE_STEP = 82


@functools.cache
def joint_tosser() -> PandaSort:
    """The tosser in `joint` mode with `running_target`, the control the scripted throw uses."""
    return PandaSort(control_mode=MODE_JOINT, running_target=True, tosser=True)


@jax.jit
def starts(params):
    """STARTS episodes' first states under `params`."""
    return jax.vmap(joint_tosser().reset, in_axes=(0, None))(jax.random.split(jax.random.key(0), STARTS), params)


@jax.jit
def thrown(states, throws, params):
    """THROW_STEPS steps of each of the batched `throws` from its state: per env and step, [3] the scores (own
    bin, another, floor), [7] the arm's joint speeds and [] the grasp potential."""
    env = joint_tosser()

    def one(state, throw):
        def step(state, t):
            state = env.step(state, throw_action(state.obs, t, throw, params), params)
            terms = state.info.reward_terms
            scored = jnp.stack([terms.correct_bin, terms.wrong_bin, terms.floor])
            grasp = state.sim.potential[SHAPING_TERMS.index("grasp")]
            return state, (scored, state.sim.qvel[env.ids.robot.arm_qpos], grasp)

        return jax.lax.scan(step, state, jnp.arange(THROW_STEPS))[1]

    return jax.vmap(one)(states, throws)


def own_bins(states) -> np.ndarray:
    """[B, 2] the centre of each batched start's object's own bin."""
    return np.array(joint_tosser().layout.bin_centers)[np.asarray(states.sim.shape[:, 0])]


def scored_in_own_bin(scored, joint_speed) -> int:
    """How many of the batch's throws scored +500, asserting every arm joint stayed under Franka's limits."""
    speed_fraction = np.abs(np.asarray(joint_speed)) / PANDA.joint_limits.speed
    assert speed_fraction.max() <= 1.0, speed_fraction.max(axis=(0, 1))
    return int(np.sum(np.asarray(scored)[..., 0] == 500.0))


@pytest.mark.mjx
def test_the_arm_throws_held_objects_into_their_bins_within_franka_speed_limits():
    """The scripted throw from held starts, in `joint` mode with `running_target` and the default joint_step
    (0.1 rad: 2.5 rad/s at full action), aimed at each object's own bin: objects ride the wind-up and the swing,
    fly and score +500, with every arm joint under Franka's speed limits.

    Measured (CPU, MJX-JAX, the tosser's firm grip, the wrist swinging at 0.55 of its limit): of 8 held starts
    released after step 82, 7 scored, after 83 three (long), after 81 none (short), the fastest joint at 84% of its
    limit; the landing moves 0.1-0.4 m per step of release, more than a bin's width, so one release step does not
    serve every object size. Started a quarter or half step earlier or later (`swing_start`), 3-6 scored.
    """
    env = joint_tosser()
    params = env.default_params().replace(held_start_prob=jnp.float32(1.0))
    states = starts(params)
    throws = jax.vmap(lambda bin_xy: aimed_throw(env.start_qpos, bin_xy, SWING_START, RELEASE_STEP))(
        jnp.asarray(own_bins(states))
    )
    scored, joint_speed, _ = thrown(states, throws, params)
    assert scored_in_own_bin(scored, joint_speed) >= 3


WOUND_UP_RELEASE_STEP = 16


@pytest.mark.mjx
def test_wound_up_starts_hold_the_object_facing_its_bin_and_their_swing_scores():
    """`wind_up_start_prob` starts a held object at the throw's wind-up posture, turned to its own bin: the
    object sits between the pads (the grasp term full), and the throw's swing alone, from rest there, scores.

    Measured (CPU, MJX-JAX, the wrist swinging at 0.55 of its limit): of 8 wound-up starts swung from step 2,
    releasing at step 15, 16 or 17 scored 4, at 14 three, the fastest joint at 86% of its limit; 3 of the others
    flew 0.25-0.36 m long at each of those. Before the wrist's servo gains were lowered, swung on without a
    release, 2 of 8 objects slipped out after 30 steps.
    """
    env = joint_tosser()
    params = env.default_params().replace(held_start_prob=jnp.float32(1.0), wind_up_start_prob=jnp.float32(1.0))
    states = starts(params)
    bins = own_bins(states)
    postures = states.sim.qpos[:, env.ids.robot.arm_qpos]
    facing = jax.vmap(wound_up_posture)(jnp.asarray(bins))
    np.testing.assert_allclose(postures, facing, atol=float(params.home_noise))
    grasp = np.asarray(states.sim.potential[:, SHAPING_TERMS.index("grasp")])
    np.testing.assert_allclose(grasp, float(params.grasp_weight), rtol=1e-6)
    # No wind-up left to make: the swing starts from rest where the arm is.
    throws = jax.vmap(
        lambda posture, bin_xy: aimed_throw(posture, bin_xy, 2.0, WOUND_UP_RELEASE_STEP).replace(wind_up=posture)
    )(postures, jnp.asarray(bins))
    scored, joint_speed, _ = thrown(states, throws, params)
    assert scored_in_own_bin(scored, joint_speed) >= 2


@pytest.mark.mjx
def test_wound_up_starts_spread_over_the_way_there_hold_their_object():
    """With `wind_up_spread` 1 a wound-up start's arm begins anywhere on the way (in joint space) from the held
    start's posture to the wind-up facing the object's bin, the object between the pads: held still there, the
    arm keeps every object in its grip."""
    env = joint_tosser()
    params = env.default_params().replace(
        held_start_prob=jnp.float32(1.0), wind_up_start_prob=jnp.float32(1.0), wind_up_spread=jnp.float32(1.0)
    )
    states = starts(params)
    bins = own_bins(states)
    postures = np.asarray(states.sim.qpos[:, env.ids.robot.arm_qpos])
    way = np.asarray(jax.vmap(wound_up_posture)(jnp.asarray(bins))) - env.start_qpos
    fraction = np.sum((postures - env.start_qpos) * way, axis=1) / np.sum(way * way, axis=1)
    np.testing.assert_allclose(postures, env.start_qpos + fraction[:, None] * way, atol=2 * float(params.home_noise))
    assert fraction.min() < 0.4 and fraction.max() > 0.6, fraction
    grasp_weight = float(params.grasp_weight)
    np.testing.assert_allclose(states.sim.potential[:, SHAPING_TERMS.index("grasp")], grasp_weight, rtol=1e-6)
    # A plan that never swings nor lets go: the arm holds still, the fingers closed.
    stay = jax.vmap(lambda posture, bin_xy: aimed_throw(posture, bin_xy, 1e3, 1000).replace(wind_up=posture))(
        jnp.asarray(postures), jnp.asarray(bins)
    )
    scored, _, grasp = thrown(states, stay, params)
    assert not np.any(np.asarray(scored))
    assert np.asarray(grasp)[:, -1].min() > 0.9 * grasp_weight, np.asarray(grasp)[:, -1]
