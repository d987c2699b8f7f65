"""TD3's deterministic tanh actor and its ensemble of Q critics (one set of params per critic, stacked).

For camera observations the networks read the image through conv encoders (`encoders.PixelEncoder`), laid out
by `TD3Networks`: one per network, every critic of the ensemble too (stacked params keep the ensemble a single
vmap), or, with a shared encoder, one as in DrQ: trained by the critics' loss alone, its features read by every
critic head and, without a gradient, by the actor.
"""

import dataclasses
from collections.abc import Mapping, Sequence
from functools import partial
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.agents.common.encoders import PixelEncoder
from jaxarm.agents.common.networks import MLP, apply_module
from jaxarm.agents.td3.config import TD3Config
from jaxarm.agents.td3.losses import expected_values
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
    """(obs [..., O] (or a camera observation, through `encoder`), action [..., A]) -> Q [...], or with `atoms`
    N > 0 the logits [..., N] of a categorical distribution of the return over N atoms."""

    hidden_sizes: Sequence[int]
    activation: str = "relu"
    encoder: PixelEncoder | None = None
    atoms: int = 0

    @nn.compact
    def __call__(self, obs: Observation, action: jax.Array) -> jax.Array:
        features = obs if self.encoder is None else self.encoder(obs)
        inputs = jnp.concatenate([features, action], axis=-1)
        outputs = MLP(self.hidden_sizes, max(self.atoms, 1), self.activation)(inputs)
        return outputs if self.atoms else outputs[..., 0]


def init_critics(critic: Critic, key: jax.Array, num_critics: int, obs: Observation, action: jax.Array):
    """Independent params of `num_critics` critics, every leaf stacked on a leading [num_critics] axis.

    The critics are initialised one after another: their orthogonal initialisations, vmapped, become batched QR
    factorisations, and two of those deadlock jaxlib 0.10.2's CPU runtime in its thread pool, as MJX's batched
    Cholesky factorisations do (README): td3_peg_pixels' critics with their own encoders (2026-11-24), then its
    shared encoder's heads, whose init hung within 300 repeats on the 2-core CPU (2026-11-29). One after another,
    flat critics' params are the vmapped ones bit for bit (CPU).
    """
    keys = jax.random.split(key, num_critics)
    return jax.lax.map(lambda critic_key: critic.init(critic_key, obs, action), keys)


def apply_critics(critic: Critic, params, obs: Observation, action: jax.Array) -> jax.Array:
    """Every critic's output: stacked params, obs [B, ...], action [B, A] -> Q [num_critics, B] (or logits
    [num_critics, B, N] of distributional critics)."""
    return jax.vmap(partial(apply_module, critic), in_axes=(0, None, None))(params, obs, action)


Params = Mapping[str, Any]


@dataclasses.dataclass(frozen=True)
class TD3Networks:
    """The actor and the critic ensemble as functions of their params, whatever the encoders' layout.

    Observations reach the heads through `encode` (raw where each network encodes its own, or where they are
    flat): `action(actor_params, encode(critic_params, obs))` and `q(critic_params, encode(critic_params, obs),
    action)`, so a shared encoder runs once per batch of observations.

    Attributes:
      actor: the actor (with its own encoder, or a head of the shared encoder's features).
      critic: one critic of the ensemble (likewise).
      shared_encoder: the encoder whose params the critic params hold under "encoder", beside the stacked
        heads under "heads"; None where each network has its own or there is none.
      atoms: [N] the return values of distributional critics' atoms; None where the critics output Q.
    """

    actor: Actor
    critic: Critic
    shared_encoder: PixelEncoder | None
    atoms: np.ndarray | None = None

    def init(self, actor_key: jax.Array, critic_key: jax.Array, num_critics: int, obs: Observation, action):
        """(actor params, critic params) for one unbatched observation and action [A]."""
        if self.shared_encoder is None:
            return self.actor.init(actor_key, obs), init_critics(self.critic, critic_key, num_critics, obs, action)
        encoder_key, critic_key = jax.random.split(critic_key)
        encoder_params = self.shared_encoder.init(encoder_key, obs)
        features = apply_module(self.shared_encoder, encoder_params, obs)
        heads = init_critics(self.critic, critic_key, num_critics, features, action)
        return self.actor.init(actor_key, features), {"encoder": encoder_params, "heads": heads}

    def encode(self, critic_params: Params, obs: Observation) -> Observation | jax.Array:
        """Observations [B, ...] as the heads read them: the shared encoder's features [B, F + P], else as given."""
        if self.shared_encoder is None:
            return obs
        return apply_module(self.shared_encoder, critic_params["encoder"], obs)

    def action(self, actor_params: Params, encoded: Observation | jax.Array) -> jax.Array:
        """The actor's action [B, A] in [-1, 1]; the shared encoder gets no gradient from it."""
        if self.shared_encoder is None:
            return apply_module(self.actor, actor_params, encoded)
        return apply_module(self.actor, actor_params, jax.lax.stop_gradient(encoded))

    def q(self, critic_params: Params, encoded: Observation | jax.Array, action: jax.Array) -> jax.Array:
        """Every critic's output at the encoded observations and actions [B, A]: Q [C, B], or the logits
        [C, B, N] of distributional critics (`q_values` gives their means)."""
        heads = critic_params if self.shared_encoder is None else critic_params["heads"]
        return apply_critics(self.critic, heads, encoded, action)

    def q_values(self, outputs: jax.Array) -> jax.Array:
        """Q [C, B] from the critics' outputs (`q`): the distributions' means, or Q itself."""
        return outputs if self.atoms is None else expected_values(outputs, jnp.asarray(self.atoms))


def make_networks(config: TD3Config, action_size: int, camera: bool = False) -> TD3Networks:
    """TD3's networks for `config`'s sizes and activation, acting on [action_size] actions; with `camera`, for
    dict observations (`config.encoder`, one per network or `config.shared_encoder`)."""
    encoder = PixelEncoder(config.encoder, config.encoder_features) if camera else None
    shared = encoder if config.shared_encoder else None
    # A flax module is a definition: one serves every network that has its own encoder, each with its own params.
    own = None if shared else encoder
    atoms = None
    if config.critic_atoms:
        atoms = np.linspace(config.value_min, config.value_max, config.critic_atoms, dtype=np.float32)
    return TD3Networks(
        Actor(config.hidden_sizes, action_size, config.activation, own),
        Critic(config.hidden_sizes, config.activation, own, config.critic_atoms),
        shared,
        atoms,
    )
