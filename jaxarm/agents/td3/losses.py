"""TD3 / DDPG targets and losses as pure functions of arrays (C critics, B transitions, A action dims).

Bootstrapping is cut only where the task `terminated`; a time-limit truncation bootstraps from the stored
pre-reset next observation like any other step.
"""

import jax
import jax.numpy as jnp


def smoothed_target_action(target_action: jax.Array, noise: jax.Array, noise_clip: jax.Array) -> jax.Array:
    """TD3's target-policy smoothing: clip(a' + clip(noise, ±noise_clip), ±1).

    Args:
      target_action: [B, A] target actor's action at the next observation, in [-1, 1].
      noise: [B, A] unclipped Gaussian noise (already scaled by its std).
      noise_clip: [] bound on |noise|.
    Returns: [B, A].
    """
    return jnp.clip(target_action + jnp.clip(noise, -noise_clip, noise_clip), -1.0, 1.0)


def critic_target(
    next_q: jax.Array, reward: jax.Array, terminated: jax.Array, gamma: jax.Array, reward_scale: jax.Array
) -> jax.Array:
    """y = reward_scale·r + γ·(1 − terminated)·min_c Q'_c(s', a').

    Args:
      next_q: [C, B] target critics at the next observation and (smoothed) target action.
      reward: [B].
      terminated: [B] bool, the task ended at this transition (no bootstrap); truncation is not termination.
      gamma, reward_scale: [].
    Returns: [B], with no gradient.
    """
    bootstrap = gamma * (1.0 - terminated.astype(jnp.float32)) * jnp.min(next_q, axis=0)
    return jax.lax.stop_gradient(reward_scale * reward + bootstrap)


def critic_loss(q: jax.Array, target: jax.Array) -> jax.Array:
    """Sum over critics of the mean squared TD error: q [C, B], target [B] -> []."""
    return jnp.sum(jnp.mean(jnp.square(q - target), axis=-1))


def actor_loss(q: jax.Array) -> jax.Array:
    """Deterministic policy gradient objective: −mean Q of the first critic at the actor's action; q [B] -> []."""
    return -jnp.mean(q)


def polyak_update(target, online, tau: jax.Array):
    """target ← (1 − tau)·target + tau·online, leaf by leaf over matching pytrees."""
    return jax.tree.map(lambda old, new: (1.0 - tau) * old + tau * new, target, online)
