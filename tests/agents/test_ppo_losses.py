"""GAE and PPO losses on hand-worked numbers."""

import jax.numpy as jnp
import numpy as np

from jaxarm.agents.ppo import losses


def test_gae_hand_worked_with_termination_truncation_and_bootstrap():
    # One env, four steps, γ = 0.5, λ = 0.5.
    rewards = jnp.array([[1.0], [2.0], [3.0], [4.0]])
    values = jnp.array([[10.0], [20.0], [30.0], [40.0]])
    next_values = jnp.array([[20.0], [100.0], [40.0], [8.0]])  # step 1 truncates: bootstrap from its own final obs
    terminated = jnp.array([[0.0], [0.0], [1.0], [0.0]])
    done = jnp.array([[0.0], [1.0], [1.0], [0.0]])
    advantages, targets = losses.gae(rewards, values, next_values, terminated, done, 0.5, 0.5)
    # δ3 = 4 + 0.5·8 − 40 = −32;          A3 = −32
    # δ2 = 3 + 0 − 30 = −27 (terminated);  A2 = −27 (done: no recursion)
    # δ1 = 2 + 0.5·100 − 20 = 32 (truncated: bootstrap); A1 = 32 (done)
    # δ0 = 1 + 0.5·20 − 10 = 1;            A0 = 1 + 0.25·32 = 9
    np.testing.assert_allclose(advantages[:, 0], [9.0, 32.0, -27.0, -32.0])
    np.testing.assert_allclose(targets[:, 0], [19.0, 52.0, 3.0, 8.0])


def test_clipped_policy_loss_hand_worked():
    old = jnp.log(jnp.array([0.5, 0.5]))
    new = jnp.log(jnp.array([0.75, 0.25]))  # ratios 1.5 and 0.5
    advantages = jnp.array([2.0, -2.0])
    loss, approx_kl, clip_fraction = losses.clipped_policy_loss(new, old, advantages, 0.2)
    # min(1.5·2, 1.2·2) = 2.4; min(0.5·−2, 0.8·−2) = −1.6; loss = −mean(2.4, −1.6) = −0.4
    np.testing.assert_allclose(loss, -0.4, rtol=1e-6)
    np.testing.assert_allclose(clip_fraction, 1.0)
    expected_kl = np.mean([(1.5 - 1) - np.log(1.5), (0.5 - 1) - np.log(0.5)])
    np.testing.assert_allclose(approx_kl, expected_kl, rtol=1e-5)


def test_value_loss_and_normalize():
    np.testing.assert_allclose(losses.value_loss(jnp.array([1.0, 3.0]), jnp.array([0.0, 1.0])), 1.25)
    normalized = losses.normalize(jnp.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose([normalized.mean(), normalized.std()], [0.0, 1.0], atol=1e-5)
