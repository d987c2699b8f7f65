"""The Gymnasium adapters: API checks, seeding, terminated vs truncated, SAME_STEP auto-reset, validation."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from jaxarm import envs
from jaxarm.interop.gymnasium_env import GymnasiumEnv, GymnasiumVectorEnv

NUM_ENVS = 3


def arm2d_params(**overrides):
    env = envs.make("arm2d")
    return env, envs.override_params(env.default_params(), overrides)


def test_single_env_passes_gymnasiums_checker():
    env, params = arm2d_params()
    with warnings.catch_warnings():
        # Unbounded observation Boxes and the missing registry spec are all check_env warns about.
        warnings.simplefilter("ignore")
        check_env(GymnasiumEnv(env, params, render_mode="rgb_array"))


def test_same_seed_same_episode_and_numpy_types():
    env, params = arm2d_params(goal_mode=1)
    first, second = GymnasiumEnv(env, params), GymnasiumEnv(env, params)
    obs_a, _ = first.reset(seed=7)
    obs_b, _ = second.reset(seed=7)
    np.testing.assert_array_equal(obs_a, obs_b)
    assert obs_a.dtype == np.float32 and obs_a.shape == env.spec.observation_shape
    assert not np.array_equal(first.reset(seed=8)[0], obs_a)
    obs, reward, terminated, truncated, info = second.step(np.full(2, 0.5, np.float32))
    assert isinstance(reward, float) and isinstance(terminated, bool) and isinstance(truncated, bool)
    assert obs in second.observation_space and "success" in info


def test_truncated_at_time_limit_and_terminated_on_success():
    env, params = arm2d_params(max_episode_steps=3)
    gym_env = GymnasiumEnv(env, params)
    gym_env.reset(seed=0)
    flags = [gym_env.step(np.zeros(2, np.float32))[2:4] for _ in range(3)]
    assert flags == [(False, False), (False, False), (False, True)]

    # A goal square larger than the world: always on the goal, so hold_steps=1 ends the episode at step 2.
    env, params = arm2d_params(goal_size=10_000.0, hold_steps=1)
    gym_env = GymnasiumEnv(env, params)
    gym_env.reset(seed=0)
    flags = [gym_env.step(np.zeros(2, np.float32))[2:4] for _ in range(2)]
    assert flags == [(False, False), (True, False)]


def test_bad_actions_raise_clear_errors():
    env, params = arm2d_params()
    gym_env = GymnasiumEnv(env, params)
    gym_env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        gym_env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        gym_env.step(np.zeros(3))
    vector = GymnasiumVectorEnv(env, NUM_ENVS, params)
    vector.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        vector.step(np.zeros(2))
    with pytest.raises(ValueError, match="NaN"):
        vector.step(np.full((NUM_ENVS, 2), np.nan))


def test_render_returns_rgb_frames():
    env, params = arm2d_params()
    gym_env = GymnasiumEnv(env, params, render_mode="rgb_array")
    gym_env.reset(seed=0)
    frame = gym_env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    vector = GymnasiumVectorEnv(env, NUM_ENVS, params, render_mode="rgb_array")
    vector.reset(seed=0)
    assert len(vector.render()) == NUM_ENVS
    with pytest.raises(ValueError, match="render_mode"):
        GymnasiumEnv(env, params, render_mode="human")


def test_vector_env_auto_resets_on_the_same_step():
    env, params = arm2d_params(max_episode_steps=3)
    vector = GymnasiumVectorEnv(env, NUM_ENVS, params)
    obs, _ = vector.reset(seed=0)
    assert obs.shape == (NUM_ENVS,) + env.spec.observation_shape and obs in vector.observation_space
    actions = np.full((NUM_ENVS, 2), 0.3, np.float32)
    for _ in range(2):
        obs, _, _, truncated, infos = vector.step(actions)
        assert not truncated.any() and not infos["_final_obs"].any()
        np.testing.assert_array_equal(infos["final_obs"], obs)
    obs, reward, terminated, truncated, infos = vector.step(actions)
    assert truncated.all() and not terminated.any() and reward.shape == (NUM_ENVS,)
    assert infos["_final_obs"].all() and infos["_episode"].all()
    np.testing.assert_array_equal(infos["episode"]["l"], 3)
    # The returned observation is the new episode's; the one the episode ended on is in final_obs.
    assert not np.allclose(infos["final_obs"], obs)
    assert not vector.step(actions)[3].any()


def test_camera_observations_are_a_dict_space_that_passes_the_checker():
    env = envs.make("arm2d_pixels_proprio", resolution=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(GymnasiumEnv(env, render_mode="rgb_array"))
    gym_env = GymnasiumEnv(env)
    obs, _ = gym_env.reset(seed=0)
    assert obs["image"].dtype == np.uint8 and obs["image"].shape == (16, 16, 1) and obs["proprio"].shape == (4,)
    assert obs in gym_env.observation_space
    assert gym_env.step(np.zeros(2, np.float32))[0] in gym_env.observation_space
    vector = GymnasiumVectorEnv(env, NUM_ENVS, envs.override_params(env.default_params(), {"max_episode_steps": 1}))
    obs, _ = vector.reset(seed=0)
    assert obs["image"].shape == (NUM_ENVS, 16, 16, 1) and obs in vector.observation_space
    obs, _, _, truncated, infos = vector.step(np.zeros((NUM_ENVS, 2), np.float32))
    assert truncated.all() and infos["final_obs"] in vector.observation_space


def test_vector_reset_takes_a_seed_per_env():
    env, params = arm2d_params(goal_mode=1)
    vector = GymnasiumVectorEnv(env, NUM_ENVS, params)
    obs, _ = vector.reset(seed=[5, 6, 5])
    np.testing.assert_array_equal(obs[0], obs[2])
    assert not np.array_equal(obs[0], obs[1])
    np.testing.assert_array_equal(vector.reset(seed=[5, 9, 9])[0][0], obs[0])
    with pytest.raises(ValueError, match="got 2 seeds for 3 envs"):
        vector.reset(seed=[1, 2])


def test_params_made_with_replace_are_checked_outside_jit():
    import jax

    env, params = arm2d_params()
    bad = params.replace(hold_steps=np.int32(-1))
    with pytest.raises(ValueError, match="hold_steps must be >= 0, got -1"):
        GymnasiumEnv(env, bad)
    with pytest.raises(ValueError, match="hold_steps"):
        env.reset(jax.random.PRNGKey(0), bad)
    adapter = GymnasiumVectorEnv(env, NUM_ENVS, params)
    adapter.params = bad
    with pytest.raises(ValueError, match="hold_steps"):
        adapter.reset(seed=0)


def test_every_env_is_registered_with_gymnasium_make():
    from jaxarm import envs
    from jaxarm.interop.gymnasium_env import gymnasium_id

    assert gymnasium_id("arm2d") == "jaxarm/Arm2d-v0" and gymnasium_id("panda_sort") == "jaxarm/PandaSort-v0"
    assert {gymnasium_id(name) for name in envs.names()} <= set(gym.registry)
    assert gym.make("jaxarm/Arm2d-v0", num_links=3).unwrapped.jax_env.num_links == 3, "env_kwargs reach the env"
    env = gym.make("jaxarm/Arm2d-v0", params=arm2d_params(max_episode_steps=3)[1])
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
    assert truncated and obs.shape == env.observation_space.shape
