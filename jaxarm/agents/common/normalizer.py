"""The learners' running observation normaliser: brax's running mean and std of each observation's
`statistics_part` (a flat observation whole, a camera observation's proprio part; images never).

Every function takes the learner's `enabled` switch (its `normalize_observations`): switched off, statistics
stay at their start and observations pass unchanged."""

from typing import TypeAlias

import jax
import jax.numpy as jnp
import numpy as np
from brax.training.acme import running_statistics, specs

from jaxarm.agents.common.encoders import statistics_part, with_statistics_part
from jaxarm.envs import EnvSpec, Observation

Normalizer: TypeAlias = running_statistics.RunningStatisticsState


def init(spec: EnvSpec) -> Normalizer:
    """Statistics of no observation yet (mean 0, std 1) for `spec`'s observations, every leaf an array (brax
    keeps its count and epsilon as Python numbers until a jitted function returns them)."""
    shape = statistics_part(spec.zero_observation()).shape
    return jax.tree.map(jnp.asarray, running_statistics.init_state(specs.Array(shape, jnp.float32)))


def update(normalizer: Normalizer, enabled: bool, obs: Observation) -> Normalizer:
    """`normalizer` with observations [..., ...] (any leading batch axes) added where `enabled`."""
    if not enabled:
        return normalizer
    return running_statistics.update(normalizer, statistics_part(obs))


def normalize(normalizer: Normalizer, enabled: bool, obs: Observation) -> Observation:
    """Observations [B, ...] as the networks read them: their statistics part standardised by `normalizer` where
    `enabled`, else as they are."""
    if not enabled:
        return obs
    return with_statistics_part(obs, running_statistics.normalize(statistics_part(obs), normalizer))


def numpy_mean_std(normalizer: Normalizer, enabled: bool, size: int) -> tuple[np.ndarray, np.ndarray]:
    """(mean [size], std [size]) float32 that an exported policy standardises flat observations with: the
    normaliser's where the learner normalises (`enabled`), else 0 and 1."""
    if not enabled:
        return np.zeros(size, np.float32), np.ones(size, np.float32)
    return np.asarray(normalizer.mean, np.float32), np.asarray(normalizer.std, np.float32)
