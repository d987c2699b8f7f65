"""PPO's policy and value networks, built once from a config and shared by the learner, warm starts and tests.

Both read raw observations through the learner's running normaliser (brax's), when the config keeps one. The
policy is brax's tanh-squashed Gaussian, whose parameters an MLP computes.
"""

import dataclasses
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
from brax.training import distribution
from brax.training.acme import running_statistics
from flax import struct

from jaxarm.agents.common.networks import MLP, apply_module
from jaxarm.agents.ppo.config import PPOConfig


class NetworkParams(struct.PyTreeNode):
    """Parameters of the policy and value MLPs (flax variable dicts)."""

    policy: Mapping[str, Any]
    value: Mapping[str, Any]


@dataclasses.dataclass(frozen=True)
class PPONetworks:
    """PPO's policy and value functions of (params, normaliser, raw observations [B, O]).

    Attributes:
      action_dist: brax's tanh-squashed Gaussian over [A] actions.
      policy_net: MLP from a normalised observation to the distribution's parameters (mean, raw scale) [B, 2A].
      value_net: MLP from a normalised observation to V [B, 1].
      normalize_observations: read observations through the running normaliser (else raw).
      scale_offset: added to the policy's raw scale; brax maps the raw scale through softplus, so this sets the
        initial standard deviation (pre-tanh) to exp(`initial_log_std`).
    """

    action_dist: distribution.NormalTanhDistribution
    policy_net: MLP
    value_net: MLP
    normalize_observations: bool
    scale_offset: float

    def init(self, policy_key: jax.Array, value_key: jax.Array, obs_size: int) -> NetworkParams:
        """Fresh parameters for observations of `obs_size` values."""
        dummy = jnp.zeros((1, obs_size))
        return NetworkParams(
            policy=self.policy_net.init(policy_key, dummy), value=self.value_net.init(value_key, dummy)
        )

    def normalize(self, normalizer: running_statistics.RunningStatisticsState, obs: jax.Array) -> jax.Array:
        """Observations [B, O] as the networks see them."""
        if not self.normalize_observations:
            return obs
        return running_statistics.normalize(obs, normalizer)

    def policy_params(self, params: NetworkParams, normalizer, obs: jax.Array) -> jax.Array:
        """The action distribution's parameters [B, 2A] at observations [B, O]."""
        out = apply_module(self.policy_net, params.policy, self.normalize(normalizer, obs))
        loc, raw_scale = jnp.split(out, 2, axis=-1)
        return jnp.concatenate([loc, raw_scale + self.scale_offset], axis=-1)

    def value(self, params: NetworkParams, normalizer, obs: jax.Array) -> jax.Array:
        """V [B] at observations [B, O]."""
        return apply_module(self.value_net, params.value, self.normalize(normalizer, obs))[..., 0]

    def deterministic_action(self, params: NetworkParams, normalizer, obs: jax.Array) -> jax.Array:
        """The policy's mode, tanh of the Gaussian's mean [B, A], at observations [B, O]."""
        return self.action_dist.mode(self.policy_params(params, normalizer, obs))


def make_networks(config: PPOConfig, action_size: int) -> PPONetworks:
    """PPO's networks for `config`'s sizes, activation and initial spread, acting on [action_size] actions."""
    action_dist = distribution.NormalTanhDistribution(event_size=action_size)
    return PPONetworks(
        action_dist=action_dist,
        policy_net=MLP(config.policy_hidden_sizes, action_dist.param_size, config.activation, output_scale=0.01),
        value_net=MLP(config.value_hidden_sizes, 1, config.activation),
        normalize_observations=config.normalize_observations,
        scale_offset=float(jnp.log(jnp.expm1(jnp.exp(config.initial_log_std)))),
    )
