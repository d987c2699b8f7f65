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


def n_step_returns(
    reward: jax.Array, done: jax.Array, gamma: jax.Array, n: int
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """n-step returns within a rollout of T steps: from each step t, up to `n` rewards summed with discount,
    stopping after the step that ends an episode and at the end of the rollout.

    Args:
      reward: [T, B] rewards of consecutive steps of B envs.
      done: [T, B] bool, the step ended its episode (terminated or truncated).
      gamma: [] discount factor.
      n: most steps summed.
    Returns: (returns [T, B] Σ_k γ^k r_{t+k}; last [T, B] int32, the index of the last step summed, whose next
      observation and termination the target bootstraps from; discount [T, B] γ^m for the m steps summed).
    """
    steps = reward.shape[0]
    index = jnp.arange(steps)[:, None]
    returns = jnp.zeros_like(reward)
    discount = jnp.ones_like(reward)
    last = jnp.broadcast_to(index, reward.shape).astype(jnp.int32)
    alive = jnp.ones(reward.shape, jnp.bool_)
    for k in range(n):
        later = jnp.minimum(index + k, steps - 1)
        valid = alive & (index + k < steps)
        returns = returns + jnp.where(valid, discount * jnp.take_along_axis(reward, later, 0), 0.0)
        discount = jnp.where(valid, discount * gamma, discount)
        last = jnp.where(valid, later, last)
        alive = valid & ~jnp.take_along_axis(done, later, 0)
    return returns, last, discount


def critic_target(
    next_q: jax.Array, reward: jax.Array, terminated: jax.Array, discount: jax.Array, reward_scale: jax.Array
) -> jax.Array:
    """y = reward_scale·r + discount·(1 − terminated)·min_c Q'_c(s', a').

    Args:
      next_q: [C, B] target critics at the next observation and (smoothed) target action.
      reward: [B] the reward (an n-step return: the discounted sum of the steps it covers).
      terminated: [B] bool, the task ended at this transition (no bootstrap); truncation is not termination.
      discount: [] or [B] γ, or γ^m for a return of m steps.
      reward_scale: [].
    Returns: [B], with no gradient.
    """
    bootstrap = discount * (1.0 - terminated.astype(jnp.float32)) * jnp.min(next_q, axis=0)
    return jax.lax.stop_gradient(reward_scale * reward + bootstrap)


def categorical_projection(values: jax.Array, probs: jax.Array, atoms: jax.Array) -> jax.Array:
    """C51's projection: probability masses at arbitrary values, shared out between the two nearest atoms.

    A mass at value v (clipped to the atoms' span) goes to the atoms on either side of it in proportion to how
    near each is, so the projection keeps the total mass and, inside the span, the mean.

    Args:
      values: [B, M] where each mass sits.
      probs: [B, M] the masses.
      atoms: [N] evenly spaced, increasing.
    Returns: [B, N] the masses on the atoms.
    """
    spacing = atoms[1] - atoms[0]
    position = (jnp.clip(values, atoms[0], atoms[-1]) - atoms[0]) / spacing  # [B, M] in atom units
    # Triangle weights max(0, 1 - |position - j|): the two atoms around each position, nearer weighing more
    # (exactly one where the position falls on an atom). [B, M, N]
    share = jnp.maximum(0.0, 1.0 - jnp.abs(position[..., None] - jnp.arange(atoms.shape[0])))
    return jnp.einsum("bm,bmn->bn", probs, share)


def expected_values(logits: jax.Array, atoms: jax.Array) -> jax.Array:
    """Means of categorical distributions over `atoms` [N]: logits [..., N] -> [...]."""
    return jnp.sum(jax.nn.softmax(logits, axis=-1) * atoms, axis=-1)


def distributional_critic_target(
    next_logits: jax.Array,
    reward: jax.Array,
    terminated: jax.Array,
    discount: jax.Array,
    reward_scale: jax.Array,
    atoms: jax.Array,
) -> jax.Array:
    """The categorical target: reward_scale·r + discount·(1 − terminated)·Z', projected onto the atoms, with Z' the
    distribution of the target critic whose mean is least at each transition (clipped double Q).

    Args:
      next_logits: [C, B, N] target critics' logits at the next observation and (smoothed) target action.
      reward, terminated, discount, reward_scale: as in `critic_target`.
      atoms: [N].
    Returns: [B, N] target probabilities, with no gradient.
    """
    least = jnp.argmin(expected_values(next_logits, atoms), axis=0)  # [B]
    chosen = jnp.take_along_axis(jax.nn.softmax(next_logits, axis=-1), least[None, :, None], axis=0)[0]  # [B, N]
    bootstrap = jnp.broadcast_to(discount, reward.shape) * (1.0 - terminated.astype(jnp.float32))
    values = (reward_scale * reward)[:, None] + bootstrap[:, None] * atoms
    return jax.lax.stop_gradient(categorical_projection(values, chosen, atoms))


def distributional_critic_loss(logits: jax.Array, target: jax.Array) -> jax.Array:
    """Sum over critics of the mean cross-entropy of their distributions against the target:
    logits [C, B, N], target [B, N] probabilities -> []."""
    return jnp.sum(jnp.mean(-jnp.sum(target * jax.nn.log_softmax(logits, axis=-1), axis=-1), axis=-1))


def critic_loss(q: jax.Array, target: jax.Array) -> jax.Array:
    """Sum over critics of the mean squared TD error: q [C, B], target [B] -> []."""
    return jnp.sum(jnp.mean(jnp.square(q - target), axis=-1))


def actor_loss(q: jax.Array) -> jax.Array:
    """Deterministic policy gradient objective: −mean Q of the first critic at the actor's action; q [B] -> []."""
    return -jnp.mean(q)


def polyak_update(target, online, tau: jax.Array):
    """target ← (1 − tau)·target + tau·online, leaf by leaf over matching pytrees."""
    return jax.tree.map(lambda old, new: (1.0 - tau) * old + tau * new, target, online)
