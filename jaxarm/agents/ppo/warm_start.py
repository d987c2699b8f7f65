"""Warm starts: a new PPO learner given the networks and observation statistics of one trained elsewhere.

The trained learner may have seen a different observation (three objects instead of one, say): the new env
says, per input, which input of the old observation holds the same quantity (`Env.observation_source_index`).
Inputs without a counterpart get zero weight in each network's first layer, so the new policy starts by acting
exactly as the trained one does on the shared inputs, and neutral statistics (mean 0, std 1). An input that reads
more than its counterpart in the same situation (`Env.observation_source_shift`: a target standing elsewhere) has
its mean moved by as much, so the networks read the same standardised value. The policy keeps the trained spread
whatever the two runs' `initial_log_std` (its offset moved into the output layer's bias), or with
`warm_start_spread` keeps the trained means but takes a fresh policy's spread (`with_fresh_spread`). The optimiser
state, env state and counters stay those of the fresh learner.
"""

from collections.abc import Callable, Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from brax.training.types import UInt64

from jaxarm.agents.common.networks import DENSE, dense_layer_names
from jaxarm.agents.ppo.config import PPOConfig
from jaxarm.agents.ppo.networks import NetworkParams, scale_offset
from jaxarm.agents.ppo.train import PPOState

FIRST_LAYER = f"{DENSE}0"
"""Flax's name for an MLP's input layer."""


def map_inputs(values: jax.Array, index: np.ndarray, missing: float | jax.Array) -> jax.Array:
    """[S, ...] values per source input -> [O, ...] per new input (`index` [O], −1 where there is none)."""
    known = jnp.asarray(index >= 0).reshape((-1,) + (1,) * (values.ndim - 1))
    return jnp.where(known, values[np.maximum(index, 0)], missing)


def sample_count(count) -> jax.Array:
    """brax's running-statistics count (an int, or two uint32 words without x64) as float32."""
    if isinstance(count, UInt64):
        return jnp.float32(count.hi) * jnp.float32(2.0**32) + jnp.float32(count.lo)
    return jnp.float32(count)


def transfer_network(trained: Mapping[str, Any], fresh: Mapping[str, Any], index: np.ndarray) -> dict[str, Any]:
    """A flax MLP's params: `trained`'s with the input layer's rows mapped to the new inputs.

    Raises ValueError where any other layer differs in shape from `fresh` (different hidden sizes).
    """
    layers = dict(trained["params"])
    first = layers[FIRST_LAYER]
    layers[FIRST_LAYER] = {**first, "kernel": map_inputs(first["kernel"], index, 0.0)}
    mapped = {"params": layers}
    shapes, expected = jax.tree.map(jnp.shape, mapped), jax.tree.map(jnp.shape, fresh)
    if shapes != expected:
        raise ValueError(f"cannot warm start: the trained network's layers {shapes} differ from this run's {expected}")
    return mapped


def with_scale_bias(
    policy: Mapping[str, Any], bias: Callable[[jax.Array], jax.Array], zero_weights: bool
) -> dict[str, Any]:
    """A policy MLP's params with `bias` applied to the scale half of its output layer's bias [A] (the output is
    [means A, raw scales A]), and that half's weights zeroed where `zero_weights`."""
    layers = dict(policy["params"])
    name = dense_layer_names(layers)[-1]  # the output layer
    out = layers[name]
    means = out["bias"].shape[-1] // 2
    kernel = out["kernel"].at[:, means:].set(0.0) if zero_weights else out["kernel"]
    layers[name] = {**out, "kernel": kernel, "bias": out["bias"].at[means:].set(bias(out["bias"][means:]))}
    return {"params": layers}


def with_fresh_spread(policy: Mapping[str, Any]) -> dict[str, Any]:
    """A policy MLP's params with the scale half of its output layer (weights and bias) zeroed: at every
    observation its Gaussian's standard deviation is then a fresh policy's, exp(initial_log_std), and its means
    stay as they were."""
    return with_scale_bias(policy, jnp.zeros_like, zero_weights=True)


def with_spread_kept(policy: Mapping[str, Any], source: PPOConfig, config: PPOConfig) -> dict[str, Any]:
    """A policy MLP's params trained under `source`'s `initial_log_std`, acting with `config`'s: the scale half of
    its output layer's bias moved by the difference of their offsets, so that its spread is the trained one at
    every observation."""
    moved = scale_offset(source.initial_log_std) - scale_offset(config.initial_log_std)
    return with_scale_bias(policy, lambda bias: bias + moved, zero_weights=False)


def warm_start(
    config: PPOConfig, source: PPOConfig, fresh: PPOState, trained: PPOState, index: np.ndarray, shift: np.ndarray
) -> PPOState:
    """`fresh` with `trained`'s (a `source` run's) policy, value and observation statistics, inputs mapped through
    `index` [O], their means moved by `shift` [O]; the policy's spread the trained one's, or a fresh one's where
    `config.warm_start_spread`."""
    index = np.asarray(index)
    stats = trained.normalizer
    normalizer = fresh.normalizer.replace(
        count=stats.count,
        mean=map_inputs(stats.mean, index, 0.0) + jnp.asarray(shift, stats.mean.dtype),
        std=map_inputs(stats.std, index, 1.0),
        summed_variance=map_inputs(stats.summed_variance, index, sample_count(stats.count)),
    )
    policy = transfer_network(trained.params.policy, fresh.params.policy, index)
    params = NetworkParams(
        policy=with_fresh_spread(policy) if config.warm_start_spread else with_spread_kept(policy, source, config),
        value=transfer_network(trained.params.value, fresh.params.value, index),
    )
    return fresh.replace(params=params, normalizer=normalizer)
