"""Panda sorter (MJX): kinematics against the published DH parameters, resting and grasping physics, scoring
exactly once per object, finite values under randomised params, and headless rendering.

Every test that steps the env shares one jitted single-env `reset`/`step` (compiling MJX is the slow part).
Rendering needs an offscreen GL; MUJOCO_GL defaults to egl here (Mesa's software EGL works without a GPU).
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.panda_sort import (
    IN_CORRECT_BIN,
    IN_PLAY,
    SHAPE_CUBE,
    SHAPE_CYLINDER,
    SHAPE_SPHERE,
    PandaSort,
)
from jaxarm.envs.panda_sort.curriculum import StartDraw, place_in_hand, pose_in_hand
from jaxarm.envs.panda_sort.env import OBJECT_OBS_SIZE
from jaxarm.envs.panda_sort.reward import SHAPING_TERMS
from jaxarm.envs.panda_sort.scripted import script_start, scripted_action
from jaxarm.robots import PANDA
from tests.envs.compiled import compiled, same_worker

# Craig (modified) DH parameters of the Franka Panda as published by Franka Emika.
DH_A = [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088]
DH_D = [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0]
DH_ALPHA = [0.0, -np.pi / 2, np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, np.pi / 2]
FLANGE_D = 0.107
HAND_YAW = -np.pi / 4
TCP_OFFSET = 0.1034


def dh_transform(a: float, d: float, alpha: float, theta: float) -> np.ndarray:
    """Modified-DH link transform RotX(alpha) TransX(a) RotZ(theta) TransZ(d), [4, 4]."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_hand_pose(q: np.ndarray) -> np.ndarray:
    """[7] joint angles -> [4, 4] pose of the hand (flange, turned by the hand's -45 degrees)."""
    pose = np.eye(4)
    for a, d, alpha, theta in zip(DH_A, DH_D, DH_ALPHA, q, strict=True):
        pose = pose @ dh_transform(a, d, alpha, theta)
    return pose @ dh_transform(0.0, FLANGE_D, 0.0, HAND_YAW)


pytestmark = same_worker("panda_sort")  # panda_sort3 too: the contract test groups it with panda_sort


@pytest.fixture(scope="module")
def env():
    env = compiled("panda_sort").env
    assert isinstance(env, PandaSort) and env.objects_count == 1
    return env


@pytest.fixture(scope="module")
def params(env):
    return env.default_params()


@pytest.fixture(scope="module")
def reset():
    return compiled("panda_sort").reset


class JittedStep:
    """jit(env.step), with the env and the jitted scripted policy beside it (one compile each per process)."""

    def __init__(self, env):
        self.env = env
        self._step = compiled("panda_sort").step
        self.script = jax.jit(lambda obs, script, params, bin_xy: scripted_action(env, obs, script, params, bin_xy))

    def __call__(self, state, action, params):
        return self._step(state, action, params)


@pytest.fixture(scope="module")
def step(env):
    return JittedStep(env)


def with_object(env, state, shape: int, size: float, pose, velocity=(0.0,) * 6):
    """`state` with object 0 replaced: shape, size, pose [7] (position, quaternion), velocity [6]; the stored
    shaping potential follows (under the default params)."""
    ids = env.ids
    sim = state.sim
    qpos = sim.qpos.at[ids.object_qpos[0] + np.arange(7)].set(jnp.asarray(pose, jnp.float32))
    qvel = sim.qvel.at[ids.object_qvel[0] + np.arange(6)].set(jnp.asarray(velocity, jnp.float32))
    sim = sim.replace(qpos=qpos, qvel=qvel, shape=jnp.array([shape], jnp.int32), size=jnp.array([size], jnp.float32))
    state = state.replace(sim=sim)
    return state.replace(sim=sim.replace(potential=jnp.asarray(shaping_potential(env, state, env.default_params()))))


def shaping_potential(env, state, params) -> np.ndarray:
    """[S] weighted shaping potentials of a (non-batched) state, recomputed from its sim."""
    model = env.episode_model(state.sim, params)
    return np.asarray(env.shaping_potential(env.kinematics(model, state.sim), state.sim, params))


def object_position(state) -> np.ndarray:
    return np.asarray(state.obs[0:3])


def tcp_position(state) -> np.ndarray:
    return np.asarray(state.obs[OBJECT_OBS_SIZE : OBJECT_OBS_SIZE + 3])


def run_steps(step, state, params, actions):
    """Steps through `actions`; returns the final state and the stacked reward terms (dict of [T] arrays)."""
    terms = []
    for action in actions:
        state = step(state, jnp.asarray(action, jnp.float32), params)
        terms.append(jax.tree.map(np.asarray, state.info.reward_terms))
    return state, jax.tree.map(lambda *x: np.stack(x), *terms)


def scripted_pick_and_place(step, state, params, bin_xy, max_steps=300):
    """Runs the library's scripted pick-and-place of object 0 towards `bin_xy` until the episode ends.

    Returns (final state, [T] correct-bin rewards, [T] wrong-bin rewards, [T] shaping rewards).
    """
    env = step.env
    script = script_start(env, state)
    correct, wrong, shaping = [], [], []
    for _ in range(max_steps):
        action, script = step.script(state.obs, script, params, jnp.asarray(bin_xy, jnp.float32))
        state = step(state, action, params)
        terms = state.info.reward_terms
        correct.append(float(terms.correct_bin))
        wrong.append(float(terms.wrong_bin))
        shaping.append(float(terms.shaping()))
        if bool(state.terminated):
            break
    return state, np.array(correct), np.array(wrong), np.array(shaping)


@pytest.mark.parametrize(
    "q",
    [
        PANDA.home_qpos,
        np.array([0.3, 0.2, -0.4, -1.5, 0.6, 2.0, -0.7]),
        np.array([-1.2, -0.9, 1.1, -2.6, -1.4, 0.8, 2.1]),
        np.array([2.0, 1.2, 0.5, -0.5, 2.5, 3.0, 0.3]),
    ],
)
def test_hand_pose_matches_published_dh_kinematics(env, q):
    data = mujoco.MjData(env.mj_model)
    data.qpos[env.ids.robot.arm_qpos] = q
    mujoco.mj_kinematics(env.mj_model, data)
    expected = dh_hand_pose(q)
    hand = env.ids.robot.hand_body
    np.testing.assert_allclose(data.xpos[hand], expected[:3, 3], atol=1e-3)
    np.testing.assert_allclose(data.xmat[hand].reshape(3, 3), expected[:3, :3], atol=1e-3)
    tcp = expected[:3, 3] + expected[:3, 2] * TCP_OFFSET
    np.testing.assert_allclose(data.site_xpos[env.ids.robot.tcp_site], tcp, atol=1e-3)


@pytest.mark.mjx
@pytest.mark.parametrize("shape", [SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE])
def test_dropped_object_comes_to_rest_on_the_table(env, params, reset, step, shape):
    size = 0.03
    state = with_object(env, reset(jax.random.key(1), params), shape, size, [0.5, -0.15, size + 0.1, 1, 0, 0, 0])
    state, _ = run_steps(step, state, params, [np.r_[0.0, 0.0, 0.0, 0.0, 1.0]] * 40)
    np.testing.assert_allclose(object_position(state), [0.5, -0.15, size], atol=3e-3)
    assert np.all(np.abs(np.asarray(state.obs[7:13])) < 1e-2), "still moving"
    assert int(state.info.in_play_count) == 1


@pytest.mark.mjx
def test_frictionless_bin_walls_still_stop_an_object_thrown_at_them(env, params, reset, step):
    size = 0.025
    wall_outside = env.layout.bin_centers[0][1] - env.layout.bin_half - 2 * env.layout.bin_wall_half_thickness
    x = env.layout.bin_centers[0][0]
    state = with_object(
        env,
        reset(jax.random.key(2), params),
        SHAPE_CUBE,
        size,
        [x, wall_outside - size - 0.03, size + 0.001, 1, 0, 0, 0],
        velocity=[0.0, 1.0, 0, 0, 0, 0],
    )
    state, terms = run_steps(step, state, params, [np.zeros(5)] * 15)
    assert int(state.info.in_play_count) == 1 and not np.any(terms.correct_bin) and not np.any(terms.wrong_bin)
    assert float(object_position(state)[1]) < wall_outside - size + 0.005, "the cube went through the wall"


# The largest cube turned 45 degrees is wider across its corners than the open fingers: the hand must turn.
@pytest.mark.mjx
@pytest.mark.parametrize(
    "shape, size, yaw",
    [
        (SHAPE_CUBE, 0.0375, np.pi / 4),
        (SHAPE_CYLINDER, 0.025, 0.5),
        (SHAPE_SPHERE, 0.025, 0.0),
    ],
)
def test_scripted_pick_and_place_scores_500_exactly_once(env, params, reset, step, shape, size, yaw):
    params = params.replace(toss_weight=jnp.float32(3.0))  # every shaping term in play
    pose = [0.5, -0.1, size + 0.001, np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]
    state = with_object(env, reset(jax.random.key(0), params), shape, size, pose)
    state = state.replace(sim=state.sim.replace(potential=jnp.asarray(shaping_potential(env, state, params))))
    initial_potential = float(state.sim.potential.sum())
    state, correct, wrong, shaping = scripted_pick_and_place(
        step, state, params, np.array(env.layout.bin_centers[shape])
    )
    assert bool(state.terminated), "the object never reached a bin"
    assert list(correct[correct != 0]) == [500.0] and not np.any(wrong)
    assert int(state.info.correct_count) == 1 and bool(state.episode.success)
    # Potential-based shaping telescopes: a placed object is worth every term's full weight.
    full = sum(float(getattr(params, f"{name}_weight")) for name in SHAPING_TERMS)
    np.testing.assert_allclose(shaping.sum(), full - initial_potential, atol=1e-3)
    state, terms = run_steps(step, state, params, [np.zeros(5)] * 3)
    assert not np.any(terms.correct_bin) and not np.any(terms.wrong_bin)


@pytest.mark.mjx
def test_scripted_placement_in_another_bin_scores_200_once(env, params, reset, step):
    size = 0.025
    first = with_object(env, reset(jax.random.key(0), params), SHAPE_CUBE, size, [0.45, 0.0, size + 0.001, 1, 0, 0, 0])
    state = first
    cylinder_bin = np.array(env.layout.bin_centers[SHAPE_CYLINDER])
    state, correct, wrong, shaping = scripted_pick_and_place(step, state, params, cylinder_bin)
    assert list(wrong[wrong != 0]) == [200.0] and not np.any(correct)
    assert bool(state.terminated) and not bool(state.episode.success)
    # An object in another bin is worth no potential: the shaping earned on the way is handed back.
    np.testing.assert_allclose(shaping.sum(), -float(first.sim.potential.sum()), atol=1e-3)


def curriculum_start(env, state, params, shape: int, held: bool):
    """`state` re-placed for a held (or grasp-ready) start of object 0 as `shape` (the arm as reset left it)."""
    sim = state.sim.replace(shape=jnp.array([shape], jnp.int32))
    model = env.episode_model(sim, params)
    data = env.kinematics(model, sim)
    start = StartDraw(
        focus=jnp.int32(0),
        presorted=jnp.zeros(1, bool),
        held=jnp.bool_(held),
        ready=jnp.bool_(not held),
        hover=jnp.bool_(False),
        wound_up=jnp.bool_(False),
        wind_up=jnp.float32(1.0),
        blend=jnp.float32(1.0 if held else 0.0),
    )
    sim = place_in_hand(env.ids, env.robot, sim, model, data, start)
    return state.replace(sim=sim.replace(potential=env.shaping_potential(data, sim, params)))


@pytest.mark.mjx
def test_the_pose_in_hand_of_a_tool_pointing_down_is_the_held_starts_upright_pose(env, params, reset):
    """`pose_in_hand`, for any orientation of the hand (wound-up starts), agrees with a held start's upright pose
    where the tool points down: the same centre, and the same orientation but for the hand's small tilt."""
    held = params.replace(held_start_prob=jnp.float32(1.0))
    state = reset(jax.random.key(0), held)
    model = env.episode_model(state.sim, held)
    data = env.kinematics(model, state.sim)
    pose = np.asarray(pose_in_hand(env.ids, env.robot, model, data))
    placed = np.asarray(state.sim.qpos[env.ids.object_qpos[0] + np.arange(7)])
    np.testing.assert_allclose(pose[:3], placed[:3], atol=2e-4)
    tilt = np.arccos(-float(data.site_xmat[env.ids.robot.tcp_site].reshape(3, 3)[2, 2]))
    turn = 2 * np.arccos(min(1.0, abs(float(np.dot(pose[3:], placed[3:])))))
    assert tilt < 0.05 and turn <= tilt + 1e-3, (turn, tilt)


@pytest.mark.mjx
@pytest.mark.parametrize("shape", [SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE])
def test_a_held_start_puts_the_object_between_the_fingers_and_it_stays_there(env, params, reset, step, shape):
    held = params.replace(held_start_prob=jnp.float32(1.0))
    state = curriculum_start(env, reset(jax.random.key(int(shape)), held), held, shape, held=True)
    start = object_position(state) - tcp_position(state)
    state, _ = run_steps(step, state, held, [np.r_[0.5, 0.5, 0.5 * (k < 10), 0.0, -1.0] for k in range(30)])
    assert int(state.info.in_play_count) == 1 and float(object_position(state)[2]) > 0.2
    np.testing.assert_allclose(object_position(state) - tcp_position(state), start, atol=0.015)
    resting = reset(jax.random.key(int(shape)), params)
    assert float(object_position(resting)[2]) < 0.05, "without a held start the object rests on the table"


@pytest.mark.mjx
@pytest.mark.parametrize("shape", [SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE])
def test_a_grasp_ready_start_closes_on_the_object_and_lifts_it(env, params, reset, step, shape):
    ready = params.replace(ready_start_prob=jnp.float32(1.0), size_scale_low=jnp.float32(1.5))  # the largest
    state = curriculum_start(env, reset(jax.random.key(10 + int(shape)), ready), ready, shape, held=False)
    np.testing.assert_allclose(object_position(state)[:2], tcp_position(state)[:2], atol=1e-6)
    state, terms = run_steps(
        step, state, ready, [np.r_[0.0, 0.0, 0.0, 0.0, -1.0]] * 8 + [np.r_[0.0, 0.0, 0.5, 0.0, -1.0]] * 30
    )
    assert float(object_position(state)[2]) > 0.1, "the object did not come up with the hand"
    assert terms.grasp.sum() == pytest.approx(float(ready.grasp_weight)) and terms.lift.sum() > 0


@pytest.fixture(scope="module")
def env3():
    return compiled("panda_sort3").env


@pytest.fixture(scope="module")
def step3():
    return compiled("panda_sort3").step


def listed_objects(env, obs: np.ndarray) -> np.ndarray:
    """[..., O] observations -> [..., N, OBJECT_OBS_SIZE] the object rows in the order they are listed."""
    return obs[..., : env.objects_count * OBJECT_OBS_SIZE].reshape(*obs.shape[:-1], env.objects_count, OBJECT_OBS_SIZE)


def batched_resets(params, seed: int, count: int = 64):
    """`count` jitted resets of panda_sort3 -> (states, [count, N, 3] object positions, [count, 3] tool centres)."""
    sorter3 = compiled("panda_sort3")
    env = sorter3.env
    states = sorter3.batched_reset(jax.random.split(jax.random.key(seed), count), params)
    positions = np.asarray(states.sim.qpos[:, env.ids.object_qpos[:, None] + np.arange(3)])
    at = env.objects_count * OBJECT_OBS_SIZE
    return states, positions, np.asarray(states.obs[:, at : at + 3])


@pytest.mark.mjx
def test_grasp_ready_starts_keep_other_objects_clear_of_the_hand(env3):
    params = env3.default_params().replace(ready_start_prob=jnp.float32(1.0))
    _, positions, tcp = batched_resets(params, seed=11)
    offsets = np.linalg.norm(positions[:, :, :2] - tcp[:, None, :2], axis=-1)  # [64, 3]
    focus = offsets.argmin(axis=1)
    assert offsets.min(axis=1).max() < 1e-5, "one object sits right under the tool"
    assert set(focus) == {0, 1, 2}, "every slot is the curriculum's object in some episodes"
    others = np.sort(offsets, axis=1)[:, 1:]
    assert others.min() > 0.1
    low = tcp[:, 2] < 0.045
    assert 0.3 < low.mean() < 0.7, "about half start with the fingers around the object"
    assert np.all(tcp[~low, 2] > 0.085) and tcp[~low, 2].max() > 0.2, "the others hover over it"


@pytest.mark.mjx
def test_presorted_starts_leave_one_object_in_play_worth_its_own_placement(env3):
    params = env3.default_params()
    weights = np.array([getattr(params, f"{name}_weight") for name in SHAPING_TERMS])
    presorted = params.replace(presorted_prob=jnp.float32(1.0))
    full, _, _ = batched_resets(params, seed=12, count=16)
    states, positions, _ = batched_resets(presorted, seed=12, count=16)
    assert np.all(np.asarray(full.info.in_play_count) == 3), "by default every object starts in play"
    assert np.all(np.asarray(states.info.in_play_count) == 1) and np.all(np.asarray(states.info.correct_count) == 2)
    out = np.asarray(states.sim.outcome) == IN_CORRECT_BIN  # [16, 3]
    assert set(np.argmin(out, axis=1)) == {0, 1, 2}, "the object left in play is any slot"
    assert np.all(positions[out][:, 0] > 2.0), "the presorted objects are parked, away from everything"
    obs = listed_objects(env3, np.asarray(states.obs))
    assert np.all(obs[:, 1:] == 0.0), "the object in play is the target, listed first; the others are zeroed"
    assert np.all(np.asarray(states.sim.target) == np.argmin(out, axis=1)) and np.all(np.abs(obs[:, 0]).sum(-1) > 0)
    # A presorted object holds every potential at its maximum: 2 x the weights above the in-play object's.
    assert np.all(np.asarray(states.sim.potential) >= 2 * weights - 1e-5)
    assert not np.any(np.asarray(states.episode.success)) and not np.any(np.asarray(states.terminated))


def drop_into_own_bin(env, state, slot: int):
    """`state` with object `slot` held 12 cm above the centre of its own bin."""
    own_bin = env.layout.bin_centers[int(state.sim.shape[slot])]
    pose_idx = env.ids.object_qpos[slot] + np.arange(7)
    return state.replace(
        sim=state.sim.replace(qpos=state.sim.qpos.at[pose_idx].set(jnp.array([*own_bin, 0.12, 1, 0, 0, 0])))
    )


def test_a_one_object_observation_maps_onto_the_target_of_three(env, env3):
    index = env3.observation_source_index(env)
    size = OBJECT_OBS_SIZE
    assert index.shape == env3.spec.observation_shape
    np.testing.assert_array_equal(index[:size], np.arange(size))
    np.testing.assert_array_equal(index[size : 3 * size], -1)
    np.testing.assert_array_equal(index[3 * size :], size + np.arange(env.spec.observation_size - size))
    with pytest.raises(ValueError, match="no mapping"):
        env3.observation_source_index(envs.make("arm2d"))


@pytest.mark.mjx
@pytest.mark.slow
def test_a_presorted_episode_succeeds_when_its_last_object_lands_in_its_bin(env3, step3):
    params = env3.default_params().replace(presorted_prob=jnp.float32(1.0))
    state = compiled("panda_sort3").reset(jax.random.key(13), params)
    focus = int(np.argmin(np.asarray(state.sim.outcome) == IN_CORRECT_BIN))
    state, terms = run_steps(step3, drop_into_own_bin(env3, state, focus), params, [np.zeros(5)] * 20)
    assert list(terms.correct_bin[terms.correct_bin != 0]) == [500.0], "only the in-play object earns a placement"
    assert int(state.info.correct_count) == 3 and bool(state.episode.success) and bool(state.terminated)


@pytest.mark.mjx
@pytest.mark.slow
def test_the_target_is_listed_first_shaped_alone_and_handed_on_to_the_nearest_object(env3, step3):
    params = env3.default_params()
    state = compiled("panda_sort3").reset(jax.random.key(14), params)

    def check_target_listed_and_shaped(state) -> tuple[int, np.ndarray, np.ndarray]:
        """Asserts the target's row comes first and its reach alone is shaped; (target, [3, 3] object
        positions, [3] tool centre)."""
        target = int(state.sim.target)
        positions = np.asarray(state.sim.qpos[env3.ids.object_qpos[:, None] + np.arange(3)])
        listed = listed_objects(env3, np.asarray(state.obs))
        np.testing.assert_allclose(listed[0, :3], positions[target], atol=1e-6)
        order = (target + np.arange(3)) % 3
        in_play = np.asarray(state.sim.outcome)[order] == IN_PLAY
        np.testing.assert_allclose(listed[:, :3], positions[order] * in_play[:, None], atol=1e-6)
        tcp = np.asarray(state.obs[3 * OBJECT_OBS_SIZE : 3 * OBJECT_OBS_SIZE + 3])
        reach = float(params.reach_weight) * (
            1 - np.tanh(np.linalg.norm(positions[target] - tcp) / float(params.reach_scale))
        )
        placed = int(state.info.correct_count)
        np.testing.assert_allclose(
            float(state.sim.potential[0]), reach + placed * float(params.reach_weight), rtol=1e-4
        )
        return target, positions, tcp

    first, _, _ = check_target_listed_and_shaped(state)
    state, terms = run_steps(step3, drop_into_own_bin(env3, state, first), params, [np.zeros(5)] * 20)
    assert list(terms.correct_bin[terms.correct_bin != 0]) == [500.0] and int(state.info.in_play_count) == 2
    second, positions, tcp = check_target_listed_and_shaped(state)
    in_play = np.flatnonzero(np.asarray(state.sim.outcome) == IN_PLAY)
    assert second == in_play[np.argmin(np.linalg.norm(positions[in_play] - tcp, axis=-1))], "not the nearest"


@pytest.mark.mjx
@pytest.mark.parametrize("shape", [SHAPE_CUBE, SHAPE_CYLINDER, SHAPE_SPHERE])
def test_each_shape_dropped_into_its_bin_scores_500_once(env, params, reset, step, shape):
    size = 0.025
    own_bin = env.layout.bin_centers[shape]
    state = with_object(env, reset(jax.random.key(3), params), shape, size, [*own_bin, 0.12, 1, 0, 0, 0])
    state, terms = run_steps(step, state, params, [np.zeros(5)] * 20)
    assert list(terms.correct_bin[terms.correct_bin != 0]) == [500.0] and not np.any(terms.wrong_bin)
    assert int(state.info.correct_count) == 1 and bool(state.episode.success) and bool(state.terminated)


@pytest.mark.mjx
def test_wrong_bin_scores_200_once_and_the_object_leaves_play(env, params, reset, step):
    size = 0.025
    sphere_bin = env.layout.bin_centers[SHAPE_SPHERE]
    state = with_object(env, reset(jax.random.key(3), params), SHAPE_CUBE, size, [*sphere_bin, 0.12, 1, 0, 0, 0])
    state, terms = run_steps(step, state, params, [np.zeros(5)] * 20)
    assert list(terms.wrong_bin[terms.wrong_bin != 0]) == [200.0] and not np.any(terms.correct_bin)
    assert int(state.info.wrong_count) == 1 and not bool(state.episode.success)
    np.testing.assert_array_equal(np.asarray(state.obs[:OBJECT_OBS_SIZE]), 0.0)


@pytest.mark.mjx
def test_object_pushed_off_the_table_costs_50_once(env, params, reset, step):
    size = 0.025
    state = with_object(
        env,
        reset(jax.random.key(4), params),
        SHAPE_SPHERE,
        size,
        [0.8, -0.1, size, 1, 0, 0, 0],
        velocity=[1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    )
    state, terms = run_steps(step, state, params, [np.zeros(5)] * 20)
    assert list(terms.floor[terms.floor != 0]) == [-50.0]
    assert int(state.info.floor_count) == 1 and bool(state.terminated)


@pytest.mark.mjx
def test_in_play_objects_never_score_and_the_bin_counts_are_consistent(env, params, reset, step):
    state, terms = run_steps(step, reset(jax.random.key(5), params), params, [np.zeros(5)] * 5)
    assert not np.any(terms.correct_bin) and not np.any(terms.wrong_bin) and not np.any(terms.floor)
    assert int(state.info.in_play_count) == 1 and int(state.sim.outcome[0]) != IN_CORRECT_BIN


@pytest.mark.mjx
@pytest.mark.slow
def test_random_actions_stay_finite_with_per_env_randomised_params():
    env = envs.make("panda_sort3")
    num_envs, steps = 8, 40
    base = env.default_params()
    key = jax.random.key(6)
    scale = jax.random.uniform(key, (num_envs,), minval=0.5, maxval=1.5)
    params = jax.tree.map(lambda leaf: jnp.broadcast_to(leaf, (num_envs, *leaf.shape)), base)
    params = params.replace(
        object_friction=base.object_friction * scale,
        mass_scale=scale,
        size_scale_high=1.0 + 0.5 * scale,
    )
    batch = envs.VmapEnv(envs.AutoReset(env), num_envs, batched_params=True)

    @jax.jit
    def rollout(key):
        def body(state, step_key):
            action = jax.random.uniform(step_key, (num_envs, *env.spec.action_shape), minval=-1.0, maxval=1.0)
            state = batch.step(state, action, params)
            return state, (state.obs, state.reward)

        reset_key, steps_key = jax.random.split(key)
        return jax.lax.scan(body, batch.reset(reset_key, params), jax.random.split(steps_key, steps))[1]

    obs, reward = rollout(key)
    assert obs.shape == (steps, num_envs, *env.spec.observation_shape)
    assert np.all(np.isfinite(np.asarray(obs))) and np.all(np.isfinite(np.asarray(reward)))


@pytest.mark.mjx
def test_render_frame_is_an_rgb_image(env, params, reset):
    frame = env.render(reset(jax.random.key(7), params), params, height=120, width=160)
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 5.0, "a blank frame"


@pytest.mark.mjx
def test_an_action_reaches_the_servos_after_the_latency(env, params, reset, step):
    state = reset(jax.random.key(4), params)
    late = envs.override_params(params, {"action_latency": 1})
    action = jnp.array([1.0, -1.0, 0.5, 0.5, -1.0])
    delayed = step(state, action, late)
    held = step(state, jnp.zeros(5), params)
    np.testing.assert_array_equal(delayed.sim.qpos, held.sim.qpos)  # the queue starts with zero actions
    np.testing.assert_array_equal(step(delayed, jnp.zeros(5), late).sim.qpos, step(held, action, params).sim.qpos)


@pytest.mark.mjx
def test_observation_noise_changes_what_is_seen_and_not_what_happens(env, params, reset, step):
    state = reset(jax.random.key(4), params)
    noisy = envs.override_params(params, {"obs_noise": 0.01, "object_pose_noise": 0.02})
    action = jnp.array([0.5, 0.5, -0.5, 0.0, 1.0])
    clean_step, noisy_step = step(state, action, params), step(state, action, noisy)
    np.testing.assert_array_equal(clean_step.sim.qpos, noisy_step.sim.qpos)
    seen = np.asarray(noisy_step.obs - clean_step.obs)
    tool = seen[OBJECT_OBS_SIZE:]
    assert 0.005 < tool.std() < 0.02
    # The object's position carries both noises: sqrt(0.01² + 0.02²) = 0.022 per axis.
    assert 0.01 < np.abs(seen[:3]).max() < 0.1
