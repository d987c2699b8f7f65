"""The ceilings suite: its FLOP counts by hand, its two versions of the two-link maths agreeing, and a small run."""

import jax
import jax.numpy as jnp
import numpy as np

from experiments import configs
from experiments.benchmarks import ceilings
from jaxarm import envs
from jaxarm.envs.arm2d.env import link_end_positions


def test_mlp_flops_counts_two_per_multiply_add():
    assert ceilings.mlp_flops((9, 64, 64, 4)) == 2 * (9 * 64 + 64 * 64 + 64 * 4)
    assert ceilings.mlp_flops((5, 1)) == 10


def test_ppo_update_flops_of_the_arm2d_preset():
    # 1,024 envs x 16 steps; rollout: one policy and two value passes per sample; 4 epochs of SGD at
    # ~3 forward passes of both nets per sample.
    policy, value = 2 * (9 * 64 + 64 * 64 + 64 * 4), 2 * (9 * 64 + 64 * 64 + 64 * 1)
    expected = 16_384 * (policy + 2 * value) + 16_384 * 4 * 3 * (policy + value)
    assert ceilings.ppo_update_flops(configs.get("ppo_arm2d"), 9, 2) == expected == 4_271_898_624


def test_rotation_tracks_the_sines_and_cosines_of_the_angles():
    trig, rotation = ceilings.two_link_maths(rotation=False), ceilings.two_link_maths(rotation=True)
    angles = jnp.array([0.3, 2.0])
    # The goal under the starting finger: held at first, then lost and found again as the arm wanders.
    goal = link_end_positions(angles, envs.make("arm2d").default_params())[-1]
    actions = jax.random.uniform(jax.random.PRNGKey(0), (200, 2), minval=-1, maxval=1)

    def run(maths, carry):
        return jax.lax.scan(lambda c, a: (maths(c, a), c[-1]), carry, actions)

    hold = jnp.zeros((), jnp.int32)
    (angles_end, _, _), trig_holds = run(trig, (angles, goal, hold))
    (cos_end, sin_end, _, _), rotation_holds = run(rotation, (jnp.cos(angles), jnp.sin(angles), goal, hold))
    np.testing.assert_allclose(cos_end, jnp.cos(angles_end), atol=1e-4)
    np.testing.assert_allclose(sin_end, jnp.sin(angles_end), atol=1e-4)
    assert int(trig_holds.max()) > 0 and int(trig_holds.min()) == 0
    np.testing.assert_array_equal(trig_holds, rotation_holds)


def test_suite_prints_the_bound_and_the_table(capsys):
    ceilings.main(["--seeds", "2", "--sizes", "64", "--steps", "20"])
    out = capsys.readouterr().out
    assert "GFLOP/s" in out and "2 seeds: at least" in out
    assert "| 64 |" in out and out.count("x)") == 3
