"""GAE and the PPO losses: pure functions with array shapes in their docstrings."""

import jax
import jax.numpy as jnp
from flax import struct


def gae(rewards, values, next_values, terminated, done, gamma, gae_lambda):
    """Generalised advantage estimation over a rollout with auto-resets.

    Args:
      rewards: [T, B] reward of step t.
      values: [T, B] V(obs_t).
      next_values: [T, B] V of the observation step t reached, before any auto-reset (V(final_obs_t)).
      terminated: [T, B] bool, step t ended the task: no bootstrap from next_values.
      done: [T, B] bool, step t ended the episode (terminated or truncated): the advantage recursion stops.
      gamma, gae_lambda: scalars.

    Returns:
      (advantages [T, B], value targets [T, B]).
    """
    deltas = rewards + gamma * next_values * (1.0 - terminated) - values
    continues = gamma * gae_lambda * (1.0 - done)

    def backward(next_advantage, step):
        delta, cont = step
        advantage = delta + cont * next_advantage
        return advantage, advantage

    _, advantages = jax.lax.scan(backward, jnp.zeros_like(rewards[0]), (deltas, continues), reverse=True)
    return advantages, advantages + values


@struct.dataclass
class LossTerms:
    """Scalars reported by `ppo_loss`."""

    policy_loss: jax.Array
    value_loss: jax.Array
    entropy: jax.Array
    approx_kl: jax.Array
    clip_fraction: jax.Array
    imitation: jax.Array


def clipped_policy_loss(log_prob, old_log_prob, advantages, clip_epsilon):
    """PPO's clipped surrogate. All inputs [N]; returns (loss [], approx_kl [], clip_fraction [])."""
    log_ratio = log_prob - old_log_prob
    ratio = jnp.exp(log_ratio)
    unclipped = ratio * advantages
    clipped = jnp.clip(ratio, 1.0 - clip_epsilon, 1.0 + clip_epsilon) * advantages
    loss = -jnp.mean(jnp.minimum(unclipped, clipped))
    approx_kl = jnp.mean((ratio - 1.0) - log_ratio)
    clip_fraction = jnp.mean(jnp.abs(ratio - 1.0) > clip_epsilon)
    return loss, approx_kl, clip_fraction


def value_loss(values, targets):
    """Half mean squared error. values, targets: [N]."""
    return 0.5 * jnp.mean(jnp.square(values - targets))


def imitation_loss(student_actions, teacher_actions):
    """Mean over N of the squared distance between actions [N, A]: the student's mean action against its
    teacher's (distillation's regression target)."""
    return jnp.mean(jnp.sum(jnp.square(student_actions - teacher_actions), axis=-1))


def normalize(advantages):
    """Standardises [N] advantages (zero mean, unit std)."""
    return (advantages - advantages.mean()) / (advantages.std() + 1e-8)
