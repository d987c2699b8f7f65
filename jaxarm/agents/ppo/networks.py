"""PPO's policy and value networks, built once from a config and shared by the learner, warm starts and tests.

Both read raw observations through the learner's running normaliser (brax's), when the config keeps one (of
a camera observation, its proprio part only). The policy is brax's tanh-squashed Gaussian, whose parameters an
MLP computes. A camera observation passes through a conv encoder first (`encoders.PixelEncoder`): one per
network, or with `shared_encoder` the policy's alone, whose features the value head reads too (the value
loss then trains the encoder as well). With `asymmetric`, the value MLP reads the observation's privileged part
(the env's state) through a normaliser of its own, and the policy never sees that part (`actor_observation`).
"""

import dataclasses
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
from brax.training import distribution
from flax import struct

from jaxarm.agents.common import normalizer as observation_normalizer
from jaxarm.agents.common.encoders import EncodedMLP, PixelEncoder
from jaxarm.agents.common.networks import MLP, apply_module
from jaxarm.agents.ppo.config import PPOConfig
from jaxarm.envs import EnvSpec, Observation
from jaxarm.envs.observation import PRIVILEGED, actor_observation


class NetworkParams(struct.PyTreeNode):
    """Parameters of the policy and value networks (flax variable dicts; with a shared encoder, the policy's
    holds it)."""

    policy: Mapping[str, Any]
    value: Mapping[str, Any]


@dataclasses.dataclass(frozen=True)
class PPONetworks:
    """PPO's policy and value functions of (params, normaliser, raw observations [B, ...]).

    Attributes:
      action_dist: brax's tanh-squashed Gaussian over [A] actions.
      policy_net: from a normalised observation to the distribution's parameters (mean, raw scale) [B, 2A].
      value_net: from a normalised observation to V [B, 1]; with a shared encoder, from the encoder's features.
      shared_encoder: the policy's encoder, which the value head reads through; None where each network has
        its own or there is none (flat observations).
      asymmetric: the value MLP reads obs[PRIVILEGED] alone, normalised by the critic's own normaliser.
      normalize_observations: read observations through the running normaliser (else raw).
      scale_offset: added to the policy's raw scale; brax maps the raw scale through softplus, so this sets the
        initial standard deviation (pre-tanh) to exp(`initial_log_std`).
    """

    action_dist: distribution.NormalTanhDistribution
    policy_net: MLP | EncodedMLP
    value_net: MLP | EncodedMLP
    shared_encoder: PixelEncoder | None
    normalize_observations: bool
    scale_offset: float
    asymmetric: bool = False

    def init(self, policy_key: jax.Array, value_key: jax.Array, spec: EnvSpec) -> NetworkParams:
        """Fresh parameters for `spec`'s observations."""
        dummy = spec.zero_observation((1,))
        policy = self.policy_net.init(policy_key, actor_observation(dummy))
        if self.asymmetric:
            value_input = dummy[PRIVILEGED]
        elif self.shared_encoder is not None:
            value_input = shared_features(self.shared_encoder, policy, actor_observation(dummy))
        else:
            value_input = actor_observation(dummy)
        return NetworkParams(policy=policy, value=self.value_net.init(value_key, value_input))

    def init_critic_normalizer(self, spec: EnvSpec) -> observation_normalizer.Normalizer | None:
        """Fresh statistics of the privileged part of `spec`'s observations where `asymmetric`, else None."""
        if not self.asymmetric:
            return None
        privileged = spec.observation[PRIVILEGED]
        return observation_normalizer.init(EnvSpec(observation_shape=privileged.shape, action_shape=spec.action_shape))

    def normalize(self, normalizer: observation_normalizer.Normalizer, obs: Observation) -> Observation:
        """Observations [B, ...] as the networks see them (a camera observation's proprio part normalised)."""
        return observation_normalizer.normalize(normalizer, self.normalize_observations, obs)

    def policy_params(self, params: NetworkParams, normalizer, obs: Observation) -> jax.Array:
        """The action distribution's parameters [B, 2A] at observations [B, ...] (their privileged part, if any,
        unread)."""
        out = apply_module(self.policy_net, params.policy, self.normalize(normalizer, actor_observation(obs)))
        loc, raw_scale = jnp.split(out, 2, axis=-1)
        return jnp.concatenate([loc, raw_scale + self.scale_offset], axis=-1)

    def value(self, params: NetworkParams, normalizer, obs: Observation, critic_normalizer=None) -> jax.Array:
        """V [B] at observations [B, ...]; where `asymmetric`, of their privileged part, through `critic_normalizer`
        (`init_critic_normalizer`)."""
        if self.asymmetric:
            inputs = observation_normalizer.normalize(critic_normalizer, self.normalize_observations, obs[PRIVILEGED])
        else:
            inputs = self.normalize(normalizer, actor_observation(obs))
            if self.shared_encoder is not None:
                inputs = shared_features(self.shared_encoder, params.policy, inputs)
        return apply_module(self.value_net, params.value, inputs)[..., 0]

    def deterministic_action(self, params: NetworkParams, normalizer, obs: Observation) -> jax.Array:
        """The policy's mode, tanh of the Gaussian's mean [B, A], at observations [B, ...]."""
        return self.action_dist.mode(self.policy_params(params, normalizer, obs))


def shared_features(encoder: PixelEncoder, policy: Mapping[str, Any], obs: Observation) -> jax.Array:
    """Features [B, F + P] of (normalised) camera observations through the encoder inside the policy's params."""
    return apply_module(encoder, {"params": policy["params"]["encoder"]}, obs)


def scale_offset(initial_log_std: float) -> float:
    """What the policy adds to its raw scale so that brax's softplus gives a standard deviation of
    exp(`initial_log_std`) where the raw scale is 0 (`PPONetworks.scale_offset`)."""
    return float(jnp.log(jnp.expm1(jnp.exp(initial_log_std))))


def make_networks(config: PPOConfig, action_size: int, camera: bool = False) -> PPONetworks:
    """PPO's networks for `config`'s sizes, activation and initial spread, acting on [action_size] actions; with
    `camera`, for dict observations (`config.encoder` in front of the MLPs)."""
    action_dist = distribution.NormalTanhDistribution(event_size=action_size)
    policy_head = MLP(config.policy_hidden_sizes, action_dist.param_size, config.activation, output_scale=0.01)
    value_head = MLP(config.value_hidden_sizes, 1, config.activation)
    policy_net: MLP | EncodedMLP = policy_head
    value_net: MLP | EncodedMLP = value_head
    shared_encoder = None
    if camera:
        policy_encoder = PixelEncoder(config.encoder, config.encoder_features)
        policy_net = EncodedMLP(policy_encoder, policy_head)
        if config.shared_encoder:
            shared_encoder = policy_encoder
        elif not config.asymmetric:  # an asymmetric critic reads the flat privileged state: no encoder
            value_net = EncodedMLP(PixelEncoder(config.encoder, config.encoder_features), value_head)
    return PPONetworks(
        action_dist=action_dist,
        policy_net=policy_net,
        value_net=value_net,
        shared_encoder=shared_encoder,
        normalize_observations=config.normalize_observations,
        scale_offset=scale_offset(config.initial_log_std),
        asymmetric=config.asymmetric,
    )
