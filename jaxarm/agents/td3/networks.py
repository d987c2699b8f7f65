"""TD3's deterministic tanh actor and its ensemble of Q critics (one set of params per critic, stacked)."""

from collections.abc import Sequence
from functools import partial

import flax.linen as nn
import jax
import jax.numpy as jnp

from jaxarm.agents.common.networks import MLP, apply_module


class Actor(nn.Module):
    """obs [..., O] -> action [..., A] in [-1, 1]."""

    hidden_sizes: Sequence[int]
    action_size: int
    activation: str = "relu"

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        return jnp.tanh(MLP(self.hidden_sizes, self.action_size, self.activation)(obs))


class Critic(nn.Module):
    """(obs [..., O], action [..., A]) -> Q [...]."""

    hidden_sizes: Sequence[int]
    activation: str = "relu"

    @nn.compact
    def __call__(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        return MLP(self.hidden_sizes, 1, self.activation)(jnp.concatenate([obs, action], axis=-1))[..., 0]


def init_critics(critic: Critic, key: jax.Array, num_critics: int, obs: jax.Array, action: jax.Array):
    """Independent params of `num_critics` critics, every leaf stacked on a leading [num_critics] axis."""
    return jax.vmap(critic.init, in_axes=(0, None, None))(jax.random.split(key, num_critics), obs, action)


def apply_critics(critic: Critic, params, obs: jax.Array, action: jax.Array) -> jax.Array:
    """Q of every critic: stacked params, obs [B, O], action [B, A] -> [num_critics, B]."""
    return jax.vmap(partial(apply_module, critic), in_axes=(0, None, None))(params, obs, action)
