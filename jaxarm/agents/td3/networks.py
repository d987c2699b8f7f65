"""TD3's deterministic tanh actor and its ensemble of Q critics (one set of params per critic, stacked).

For camera observations each network reads the image through its own conv encoder (`encoders.PixelEncoder`),
every critic of the ensemble too (DrQ's critics share one; stacked params keep the ensemble a single vmap).
"""

from collections.abc import Sequence
from functools import partial

import flax.linen as nn
import jax
import jax.numpy as jnp

from jaxarm.agents.common.encoders import PixelEncoder
from jaxarm.agents.common.networks import MLP, apply_module
from jaxarm.envs import Observation


class Actor(nn.Module):
    """obs [..., O] (or a camera observation, through `encoder`) -> action [..., A] in [-1, 1]."""

    hidden_sizes: Sequence[int]
    action_size: int
    activation: str = "relu"
    encoder: PixelEncoder | None = None

    @nn.compact
    def __call__(self, obs: Observation) -> jax.Array:
        features = obs if self.encoder is None else self.encoder(obs)
        return jnp.tanh(MLP(self.hidden_sizes, self.action_size, self.activation)(features))


class Critic(nn.Module):
    """(obs [..., O] (or a camera observation, through `encoder`), action [..., A]) -> Q [...]."""

    hidden_sizes: Sequence[int]
    activation: str = "relu"
    encoder: PixelEncoder | None = None

    @nn.compact
    def __call__(self, obs: Observation, action: jax.Array) -> jax.Array:
        features = obs if self.encoder is None else self.encoder(obs)
        return MLP(self.hidden_sizes, 1, self.activation)(jnp.concatenate([features, action], axis=-1))[..., 0]


def init_critics(critic: Critic, key: jax.Array, num_critics: int, obs: Observation, action: jax.Array):
    """Independent params of `num_critics` critics, every leaf stacked on a leading [num_critics] axis.

    Critics with an encoder are initialised one after another: their orthogonal initialisations, vmapped, become
    batched QR factorisations, and two of those deadlocked jaxlib 0.10.2's CPU runtime in its thread pool
    (td3_peg_pixels, 2026-11-24), as MJX's batched Cholesky factorisations do (README).
    """
    keys = jax.random.split(key, num_critics)
    if critic.encoder is not None:
        return jax.lax.map(lambda critic_key: critic.init(critic_key, obs, action), keys)
    return jax.vmap(critic.init, in_axes=(0, None, None))(keys, obs, action)


def apply_critics(critic: Critic, params, obs: Observation, action: jax.Array) -> jax.Array:
    """Q of every critic: stacked params, obs [B, ...], action [B, A] -> [num_critics, B]."""
    return jax.vmap(partial(apply_module, critic), in_axes=(0, None, None))(params, obs, action)
