"""A PPO run split over 4 (forced host) devices, each stepping its own envs and taking its minibatch shares from
them, matches the single-device run within float tolerance."""

import os
import subprocess
import sys
import textwrap

import pytest

PROBE = textwrap.dedent("""
    import jax, numpy as np
    from jaxarm.agents.common.sharding import data_mesh, data_parallel, envs_split_over, state_shardings
    from jaxarm.agents.common.trainer import make_chunk_runner
    from jaxarm.agents.ppo import PPOConfig, make_trainer

    assert jax.device_count() == 4, jax.devices()
    config = PPOConfig(num_envs=16, rollout_length=4, num_minibatches=2, num_epochs=2, total_env_steps=64 * 6,
                       updates_per_chunk=3, policy_hidden_sizes=(16,), value_hidden_sizes=(16,), shuffle_groups=4)
    trainer = make_trainer(config)
    hparams = config.hparams()

    def final(state, shardings=None):
        chunk = make_chunk_runner(trainer, config.updates_per_chunk, shardings)
        for _ in range(trainer.num_updates // config.updates_per_chunk):
            state, _ = chunk(state, hparams)
        return state

    init = jax.jit(trainer.init)  # a fresh state per run: the chunk runner donates its input
    single = final(init(jax.random.PRNGKey(0), hparams))
    mesh = data_mesh()
    with envs_split_over(mesh):  # VmapEnv steps each device's envs there (over_env_batch)
        start = data_parallel(init(jax.random.PRNGKey(0), hparams), mesh)
        lowered = jax.jit(trainer.update).lower(start, hparams)
        step = lowered.as_text()
        assert any(mark in step for mark in ("sdy.manual_computation", "SPMDFullToShardShape")), "envs not split"
        # Data-parallel SGD: the devices exchange gradients (all-reduce), never samples.
        assert "all-gather" not in lowered.compile().as_text(), "samples gathered across devices"
        split = final(start, state_shardings(start, mesh))
    assert len(split.env_state.obs.sharding.device_set) == 4
    assert split.env_state.obs.sharding.spec[0] == "data"
    gap = max(float(np.max(np.abs(np.asarray(a) - np.asarray(b))))
              for a, b in zip(jax.tree.leaves(single.params), jax.tree.leaves(split.params)))
    print("max param gap", gap)
    assert gap < 1e-4, gap
""")


@pytest.mark.slow
def test_four_device_run_matches_one_device():
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=4", "JAX_PLATFORMS": "cpu"}
    result = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "max param gap" in result.stdout
