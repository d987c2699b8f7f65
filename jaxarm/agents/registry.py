"""The learners by name, and what the runner needs of each: its config class, trainer and warm start.

The names are what run directories record (config.json's "agent"), so a name, once used, stays. Code that
serves every learner (the runner, run directories, presets) looks learners up here and imports none of them.
"""

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from jaxarm.agents import ppo, td3
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.trainer import Trainer
from jaxarm.agents.ppo.warm_start import warm_start as ppo_warm_start
from jaxarm.envs.registry import closest_match_hint


@dataclasses.dataclass(frozen=True)
class Learner:
    """One learner as the runner sees it.

    Attributes:
      config_class: its run config, a `RunConfig` subclass.
      make_trainer: (config, env=None, env_params=None) -> `Trainer`; `env`, `env_params` replace the config's.
      warm_start: (fresh learner state, trained learner state, index [O]) -> the fresh state with the trained
        networks (and whatever else carries over), the new observation's input o read from the trained one's
        input index[o] (−1: none; see `Env.observation_source_index`); None where the learner has no warm start.
    """

    config_class: type[RunConfig]
    make_trainer: Callable[..., Trainer]
    warm_start: Callable[[Any, Any, np.ndarray], Any] | None = None


LEARNERS: dict[str, Learner] = {
    "ppo": Learner(ppo.PPOConfig, ppo.make_trainer, warm_start=ppo_warm_start),
    # DDPG is a TD3Config setting (one critic, no target smoothing, no policy delay), not a learner of its own.
    "td3": Learner(td3.TD3Config, td3.make_trainer),
}


def get(name: str) -> Learner:
    """The learner registered as `name`; ValueError naming the closest one for an unknown name."""
    if name not in LEARNERS:
        raise ValueError(f"unknown learner {name!r}{closest_match_hint(name, LEARNERS)}")
    return LEARNERS[name]


def name_of(config: RunConfig) -> str:
    """The name of the learner whose config class is `config`'s class; ValueError if there is none."""
    for name, learner in LEARNERS.items():
        if type(config) is learner.config_class:
            return name
    raise ValueError(f"no learner is registered for {type(config).__name__}")


def learner_for(config: RunConfig) -> Learner:
    """The learner `config` configures."""
    return LEARNERS[name_of(config)]


def make_trainer(config: RunConfig, **extras: Any) -> Trainer:
    """The trainer of the learner `config` configures, on the config's env; `extras` go to the learner's own
    `make_trainer` (PPO's loaded `teacher`)."""
    return learner_for(config).make_trainer(config, **extras)
