"""Deterministic evaluation: it stops once every episode has ended, with the results of the whole time limit."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.agents.common.evaluate import evaluate, rollout_episodes
from tests.agents.probe_envs import HOST_CHECKS, CountdownEnv, HostCheckedEnv


def test_evaluation_stops_when_every_episode_has_ended_with_the_whole_time_limits_results():
    env = CountdownEnv()
    params = env.default_params()  # episodes of 1 to 6 steps, a time limit of 20
    calls = []

    def policy(obs):
        jax.debug.callback(lambda: calls.append(1))
        return obs * 0.0

    key = jax.random.PRNGKey(0)
    result = jax.jit(lambda key: evaluate(env, params, policy, key, 64))(key)
    last = jax.tree.map(lambda leaf: leaf[-1], rollout_episodes(env, params, policy, key, 64, 20))
    np.testing.assert_array_equal(result.lengths, last.episode.length)
    np.testing.assert_array_equal(result.returns, last.episode.return_)
    assert result.successes.all() and int(result.lengths.max()) == 6
    # The fixed rollout took 20 policy steps; the evaluation as many as its longest episode.
    assert len(calls) == 20 + 6


def test_an_evaluation_checks_the_envs_host_faults_once_and_raises_on_one():
    env = HostCheckedEnv()
    params = env.default_params()
    HOST_CHECKS.clear()
    result = jax.jit(lambda key: evaluate(env, params, jnp.zeros_like, key, 16))(jax.random.key(0))
    np.testing.assert_array_equal(result.lengths, 4)
    assert HOST_CHECKS == {"checked": 1}
    faulty = params.replace(fault_at=jnp.array(3, jnp.int32))  # the episodes' last step
    with pytest.raises(Exception, match="probe fault in 16 envs"):
        jax.block_until_ready(jax.jit(lambda key: evaluate(env, faulty, jnp.zeros_like, key, 16))(jax.random.key(0)))
