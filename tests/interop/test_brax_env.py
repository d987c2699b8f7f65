"""The brax adapter: time limit, termination and auto-reset as brax's trainers read them; PPO and SAC run."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from brax.envs.wrappers import training as brax_training

from jaxarm import envs
from jaxarm.envs.arm2d import GOAL_UNIFORM_REACHABLE
from jaxarm.interop.brax_compat import BRAX_PMAP_AXIS, device_put_replicated, install_device_put_replicated
from jaxarm.interop.brax_env import BraxEnv, wrap_for_training

NUM_ENVS = 4


def make_params(**overrides):
    env = envs.make("arm2d")
    return env, envs.override_params(env.default_params(), {"goal_mode": GOAL_UNIFORM_REACHABLE, **overrides})


def run_steps(wrapped, steps):
    """Resets `wrapped` (a batched brax env) and takes `steps` zero-action steps; returns every state."""
    state = jax.jit(wrapped.reset)(jax.random.split(jax.random.PRNGKey(0), NUM_ENVS))
    step = jax.jit(wrapped.step)
    states = [state]
    for _ in range(steps):
        states.append(step(states[-1], jnp.zeros((NUM_ENVS, wrapped.action_size))))
    return states


def test_device_put_replicated_stacks_one_copy_per_device():
    tree = {"a": jnp.arange(3.0), "b": jnp.ones((2, 2), jnp.int32)}
    replicated = device_put_replicated(tree, jax.local_devices())
    assert replicated["a"].shape == (jax.local_device_count(), 3)
    assert replicated["b"].dtype == jnp.int32
    np.testing.assert_array_equal(replicated["a"][0], tree["a"])
    install_device_put_replicated()
    assert callable(jax.device_put_replicated)
    assert install_device_put_replicated() is False  # never replaces an existing one


def test_the_adapter_installs_what_brax_trainers_need(monkeypatch):
    monkeypatch.delattr(jax, "device_put_replicated", raising=False)
    env, params = make_params()
    BraxEnv(env, params)
    assert jax.device_put_replicated is device_put_replicated


def test_replicated_state_has_the_layout_brax_pmap_gives_back():
    # Any other layout makes brax's pmapped epoch compile a second time, for its own outputs.
    epoch = jax.pmap(lambda tree: jax.tree.map(lambda leaf: leaf + 1, tree), axis_name=BRAX_PMAP_AXIS)
    replicated = device_put_replicated({"a": jnp.arange(3.0)}, jax.local_devices())
    assert epoch(replicated)["a"].sharding == replicated["a"].sharding


def test_time_limit_is_truncation_and_auto_reset_is_jaxarms():
    env, params = make_params(max_episode_steps=5)
    wrapped = wrap_for_training(BraxEnv(env, params), episode_length=5)
    states = run_steps(wrapped, 6)
    last = states[5]
    np.testing.assert_array_equal(last.done, 1.0)
    np.testing.assert_array_equal(last.info["truncation"], 1.0)
    np.testing.assert_array_equal(last.info["steps"], 5.0)
    np.testing.assert_array_equal(last.info["episode_metrics"]["length"], 5.0)
    # The next episode started with a fresh goal drawn by jaxarm's AutoReset.
    np.testing.assert_array_equal(last.pipeline_state.step_count, 0)
    assert not np.allclose(last.pipeline_state.sim.goal, states[4].pipeline_state.sim.goal)
    np.testing.assert_array_equal(states[6].done, 0.0)
    assert all(float(state.info["truncation"].max()) == 0.0 for state in states[1:5])


def test_termination_is_done_without_truncation():
    # A goal square larger than the world: the finger is always on it, so hold_steps=1 ends step 2.
    env, params = make_params(goal_size=10_000.0, hold_steps=1)
    states = run_steps(wrap_for_training(BraxEnv(env, params), episode_length=200), 2)
    np.testing.assert_array_equal(states[2].done, 1.0)
    np.testing.assert_array_equal(states[2].info["truncation"], 0.0)
    np.testing.assert_array_equal(states[2].metrics["success"], 1.0)


def test_brax_wrappers_do_the_time_limit_when_auto_reset_is_off():
    env, params = make_params(max_episode_steps=5)
    wrapped = brax_training.wrap(BraxEnv(env, params, auto_reset=False), episode_length=5)
    states = run_steps(wrapped, 5)
    np.testing.assert_array_equal(states[5].done, 1.0)
    np.testing.assert_array_equal(states[5].info["truncation"], 1.0)
    # brax's AutoResetWrapper returns each env to its own first state.
    np.testing.assert_array_equal(states[5].obs, states[0].obs)


def test_wrong_wrapper_pairings_raise():
    env, params = make_params()
    with pytest.raises(ValueError, match="wrap_for_training"):
        run_steps(brax_training.wrap(BraxEnv(env, params), episode_length=200), 1)
    with pytest.raises(ValueError, match="max_episode_steps"):
        wrap_for_training(BraxEnv(env, params), episode_length=100)
    with pytest.raises(ValueError, match="auto_reset=True"):
        wrap_for_training(BraxEnv(env, params, auto_reset=False), episode_length=200)


def assert_finite_metrics(metrics):
    assert "eval/episode_reward" in metrics and "eval/episode_success" in metrics
    assert all(np.isfinite(value) for value in metrics.values())


@pytest.mark.slow
def test_brax_ppo_trains_through_the_adapter():
    from brax.training.agents.ppo import networks as ppo_networks
    from brax.training.agents.ppo import train as ppo

    env, params = make_params(max_episode_steps=20)
    steps_seen = []
    _, policy_params, metrics = ppo.train(
        environment=BraxEnv(env, params),
        wrap_env_fn=wrap_for_training,
        episode_length=20,
        num_timesteps=16 * 8 * 4 * 2,
        num_envs=16,
        unroll_length=8,
        batch_size=16,
        num_minibatches=4,
        num_updates_per_batch=2,
        num_evals=2,
        num_eval_envs=16,
        normalize_observations=True,
        network_factory=functools.partial(
            ppo_networks.make_ppo_networks, policy_hidden_layer_sizes=(16,), value_hidden_layer_sizes=(16,)
        ),
        progress_fn=lambda step, _: steps_seen.append(step),
    )
    assert steps_seen[-1] >= 16 * 8 * 4 * 2
    assert_finite_metrics(metrics)
    assert all(np.all(np.isfinite(leaf)) for leaf in jax.tree.leaves(policy_params))


@pytest.mark.slow
def test_brax_sac_trains_through_the_adapter():
    from brax.training.agents.sac import networks as sac_networks
    from brax.training.agents.sac import train as sac

    env, params = make_params(max_episode_steps=20)
    _, policy_params, metrics = sac.train(
        environment=BraxEnv(env, params),
        wrap_env_fn=wrap_for_training,
        episode_length=20,
        num_timesteps=1_000,
        num_envs=8,
        batch_size=32,
        min_replay_size=128,
        max_replay_size=2_048,
        num_evals=2,
        num_eval_envs=8,
        normalize_observations=True,
        network_factory=functools.partial(sac_networks.make_sac_networks, hidden_layer_sizes=(16,)),
    )
    assert metrics["training/sps"] > 0
    assert_finite_metrics(metrics)
    assert all(np.all(np.isfinite(leaf)) for leaf in jax.tree.leaves(policy_params))


def test_camera_observations_pass_through_with_brax_shapes():
    env = envs.make("arm2d_pixels_proprio", resolution=16)
    wrapped = wrap_for_training(BraxEnv(env, env.default_params()), episode_length=200)
    assert wrapped.observation_size == {"image": (16, 16, 1), "proprio": (4,)}
    states = run_steps(wrapped, 2)
    assert states[-1].obs["image"].shape == (NUM_ENVS, 16, 16, 1) and states[-1].obs["image"].dtype == jnp.uint8
