"""The ceilings suite: its FLOP counts by hand, its two versions of the two-link maths agreeing, and a small run."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments import configs
from experiments.benchmarks import ceilings
from jaxarm import envs
from jaxarm.agents.ppo import PPOConfig
from jaxarm.envs.arm2d.arm import link_end_positions


def test_mlp_flops_counts_two_per_multiply_add():
    assert ceilings.mlp_flops((9, 64, 64, 4)) == 2 * (9 * 64 + 64 * 64 + 64 * 4)
    assert ceilings.mlp_flops((5, 1)) == 10


def test_ppo_update_flops_of_the_arm2d_preset():
    # 1,024 envs x 16 steps; rollout: one policy and two value passes per sample; 4 epochs of SGD at
    # ~3 forward passes of both nets per sample.
    policy, value = 2 * (9 * 64 + 64 * 64 + 64 * 4), 2 * (9 * 64 + 64 * 64 + 64 * 1)
    expected = 16_384 * (policy + 2 * value) + 16_384 * 4 * 3 * (policy + value)
    config = configs.get("ppo_arm2d")
    assert isinstance(config, PPOConfig)
    assert ceilings.ppo_update_flops(config, 9, 2) == expected == 4_271_898_624


def test_both_versions_of_the_two_link_maths_hold_the_goal_as_the_env_does():
    env = envs.make("arm2d")
    params = env.default_params()
    angles = jnp.array([0.3, 2.0])
    # The goal under the starting finger: held at first, then lost and found again as the arm wanders.
    goal = link_end_positions(angles, params)[-1]
    actions = jax.random.uniform(jax.random.PRNGKey(0), (200, 2), minval=-1, maxval=1)

    def env_step(state, action):
        state = env.step(state, action, params)
        return state, state.sim

    start = env.reset(jax.random.PRNGKey(1), params)
    start = start.replace(sim=start.sim.replace(angles=angles, goal=goal, hold_count=jnp.zeros((), jnp.int32)))
    _, env_sims = jax.lax.scan(env_step, start, actions)
    expected = env_sims.hold_count
    assert int(expected.max()) > 0 and int(expected.min()) == 0

    hold = jnp.zeros((), jnp.int32)
    starts = {
        False: (angles[0], angles[1], goal[0], goal[1], hold),
        True: (jnp.cos(angles[0]), jnp.sin(angles[0]), jnp.cos(angles[1]), jnp.sin(angles[1]), goal[0], goal[1], hold),
    }
    for rotation, carry in starts.items():
        maths = ceilings.two_link_maths(rotation)

        def step(carry, action, maths=maths):
            carry = maths(carry, action)
            return carry, carry[-1]

        end, holds = jax.lax.scan(step, carry, (actions[:, 0], actions[:, 1]))
        np.testing.assert_array_equal(holds, expected)
    last = env_sims.angles[-1]
    np.testing.assert_allclose(
        end[:4], [jnp.cos(last[0]), jnp.sin(last[0]), jnp.cos(last[1]), jnp.sin(last[1])], atol=1e-4
    )


@pytest.mark.slow
def test_suite_prints_the_bound_and_the_table_and_writes_them(capsys, tmp_path):
    ceilings.main(["--seeds", "2", "--sizes", "64", "--steps", "20", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert "GFLOP/s" in out and "2 seeds: at least" in out
    assert "| 64 |" in out and out.count("x)") == 3
    written = json.loads((tmp_path / "ceilings.json").read_text())
    (row,) = written["rows"]
    assert row["envs"] == 64
    assert f"{row['two_link_rotation_steps_per_second']:.3g} (" in out
    arithmetic = written["arithmetic"]
    assert arithmetic["seeds"] == 2 and arithmetic["update_gflop"] == 4_271_898_624 / 1e9
    assert f"measured {arithmetic['seeds_update_ms']:,.0f} ms" in out
    assert written["goal_env_steps_per_second"] == ceilings.GOAL_RATIO * written["numpy_single_env_steps_per_second"]
