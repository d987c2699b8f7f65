"""arm2d against the independent numpy reference, and hand-computed cases."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm import envs
from jaxarm.envs.arm2d import GOAL_FIXED, GOAL_UNIFORM_REACHABLE, GOAL_UNIFORM_WORLD, Arm2d, Arm2dSim
from jaxarm.envs.arm2d.arm import goal_reachable
from jaxarm.envs.arm2d.numpy_reference import ClassicArm
from jaxarm.envs.observation import with_image


def start_state(env, params, angles, goal):
    """A reset state moved to the given angles and goal (hold count 0), observation recomputed."""
    state = env.reset(jax.random.key(0), params)
    sim = Arm2dSim(
        angles=jnp.asarray(angles, jnp.float32),
        goal=jnp.asarray(goal, jnp.float32),
        hold_count=jnp.zeros((), jnp.int32),
    )
    obs = env._observe(sim, params)
    if env.draws_images:
        obs = with_image(obs, env.images(sim, params))
    return state.replace(sim=sim, obs=obs)


@pytest.mark.parametrize("num_links", [2, 3, 5])
def test_parity_with_numpy_reference_on_random_action_sequences(num_links):
    env = Arm2d(num_links)
    params = env.default_params().replace(success_bonus=jnp.float32(7.0))
    rng = np.random.default_rng(num_links)
    step = jax.jit(env.step)
    for episode in range(4):
        angles = rng.uniform(0, 2 * np.pi, num_links).astype(np.float32)
        # Every other episode starts near the goal so that the bonus, holding and termination are exercised.
        goal = rng.uniform(0, 400, 2) if episode % 2 else np.array(env_finger(angles, params))
        reference = ClassicArm(link_lengths=np.asarray(params.link_lengths), success_bonus=7.0)
        np.testing.assert_allclose(
            reference.reset_to(angles, goal), start_state(env, params, angles, goal).obs, atol=1e-5
        )
        state = start_state(env, params, angles, goal)
        for _ in range(200):
            action = rng.uniform(-1.5, 1.5, num_links) * (episode % 2 or 0.05)
            obs, reward, terminated, truncated = reference.step(action)
            state = step(state, jnp.asarray(action, jnp.float32), params)
            np.testing.assert_allclose(state.obs, obs, atol=2e-5)
            np.testing.assert_allclose(state.reward, reward, atol=2e-5)
            assert bool(state.terminated) == bool(terminated) and bool(state.truncated) == bool(truncated)
            if terminated or truncated:
                break


def env_finger(angles, params):
    from jaxarm.envs.arm2d.arm import link_end_positions

    return link_end_positions(jnp.asarray(angles), params)[-1]


def test_hand_computed_goal_under_the_finger_holds_and_terminates():
    env = Arm2d()
    params = env.default_params()
    # Angles 0, 0: the arm lies along +x, so the finger is at (400, 200) and the elbow at (300, 200).
    state = start_state(env, params, [0.0, 0.0], [400.0, 200.0])
    np.testing.assert_allclose(state.obs, [1.5, 1.0, 2.0, 1.0, 0.25, 0.0, 0.0, 0.0, 0.0], atol=1e-6)
    step = jax.jit(env.step)
    zero = jnp.zeros(2)
    for count in range(1, 52):
        state = step(state, zero, params)
        np.testing.assert_allclose(state.reward, 1.0, atol=1e-6)  # distance 0, bonus 1
        assert float(state.obs[-1]) == 1.0
        assert bool(state.terminated) == (count > 50)
    assert bool(state.terminated) and not bool(state.truncated) and bool(state.last_episode.success)
    np.testing.assert_allclose(state.last_episode.return_, 51.0, atol=1e-4)


def test_hand_computed_step_of_a_quarter_turn():
    env = Arm2d()
    params = env.default_params()
    state = start_state(env, params, [np.pi / 2 - 0.1, 0.0], [100.0, 100.0])
    state = jax.jit(env.step)(state, jnp.array([1.0, -5.0]), params)  # -5 is clipped to -1
    # θ1 = π/2, θ2 = −0.1: elbow (200, 300), finger (200 + 100 sin 0.1, 300 + 100 cos 0.1).
    finger = np.array([200 + 100 * np.sin(0.1), 300 + 100 * np.cos(0.1)])
    np.testing.assert_allclose(state.obs[:4], [1.0, 1.5, *(finger / 200)], atol=1e-5)
    np.testing.assert_allclose(state.reward, -np.linalg.norm([100, 100] - finger) / 400, atol=1e-6)


def test_unreachable_goal_behaves_and_is_reported():
    env = Arm2d()
    params = env.default_params()
    state = start_state(env, params, [0.0, 0.0], [5.0, 5.0])  # 276 from the base, reach is 200
    assert not bool(goal_reachable(state.sim.goal, params))
    assert bool(goal_reachable(jnp.array([100.0, 100.0]), params))
    assert not bool(goal_reachable(jnp.array([200.0, 200.0]), params.replace(link_lengths=jnp.array([150.0, 50.0]))))
    step = jax.jit(envs.AutoReset(env).step)
    for _ in range(250):
        state = step(state, jnp.array([1.0, 1.0]), params)
        assert np.all(np.isfinite(state.obs)) and float(state.reward) < 0
        assert not bool(state.info.goal_reachable) or bool(state.done)
        if bool(state.done):
            assert bool(state.truncated)
            break
    else:
        pytest.fail("the time limit never ended the episode")


@pytest.mark.parametrize("mode", [GOAL_FIXED, GOAL_UNIFORM_WORLD, GOAL_UNIFORM_REACHABLE])
def test_goal_modes(mode):
    env = Arm2d()
    params = env.default_params().replace(goal_mode=jnp.array(mode))
    states = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(1), 2000), params)
    goals = np.asarray(states.sim.goal)
    if mode == GOAL_FIXED:
        np.testing.assert_array_equal(goals, np.tile([100.0, 100.0], (2000, 1)))
    elif mode == GOAL_UNIFORM_WORLD:
        # The reachable disc plus the goal square's margin covers ~91% of the world.
        assert (
            goals.min() >= 0 and goals.max() <= 400 and 0.05 < np.mean(~np.asarray(states.info.goal_reachable)) < 0.15
        )
    else:
        radius = np.linalg.norm(goals - 200, axis=1)
        assert radius.max() <= 200.001 and np.all(np.asarray(states.info.goal_reachable))
        assert abs(np.mean(radius < 100) - 0.25) < 0.04  # uniform over the disc's area


def test_params_vmap_is_domain_randomisation():
    env = Arm2d()
    params = env.default_params()
    lengths = jnp.array([[100.0, 100.0], [50.0, 150.0]])
    batched = jax.tree.map(lambda leaf: jnp.stack([leaf, leaf]), params).replace(link_lengths=lengths)
    batch = envs.VmapEnv(env, 2, batched_params=True)
    state = batch.reset(jax.random.key(0), batched)
    state = batch.step(state, jnp.zeros((2, 2)), batched)
    fingers = np.asarray(state.obs[:, 2:4]) * 200 - 200
    np.testing.assert_allclose(np.linalg.norm(fingers, axis=1) <= lengths.sum(1) + 1e-3, True)


def test_override_params_checks_names_and_shapes():
    params = Arm2d().default_params()
    assert float(envs.override_params(params, {"goal_size": 10}).goal_size) == 10.0
    with pytest.raises(KeyError, match="did you mean 'goal_size'"):
        envs.override_params(params, {"goal_siz": 10})
    with pytest.raises(ValueError, match="shape"):
        envs.override_params(params, {"fixed_goal": [1.0, 2.0, 3.0]})
