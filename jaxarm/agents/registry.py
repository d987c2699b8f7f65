"""The learners by name, and what the runner needs of each: its config class, trainer, and its capabilities
beyond training (a warm start, being taught, several processes per host).

The names are what run directories record (config.json's "agent"), so a name, once used, stays. Code that
serves every learner (the runner, its run directories, the CLI) looks learners up here and imports none of them:
a capability one learner has is an entry here, not a branch there (tests/envs/test_imports.py holds the runner to
it).
"""

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from jaxarm.agents import ppo, td3
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.trainer import Trainer
from jaxarm.agents.ppo.warm_start import warm_start as ppo_warm_start
from jaxarm.envs.registry import closest_match_hint


@dataclasses.dataclass(frozen=True)
class Teaching:
    """What the runner needs of a learner that can be taught (distillation, `jaxarm.agents.common.teachers`): where
    its config names the teacher. The runner loads that run's policy (`teachers.learner_as_teacher`: any learner
    teaches) and gives it to the learner's `make_trainer` as `teacher`.

    Attributes:
      teacher: config -> its teacher: a run directory, `preset:NAME` (`teachers.PRESET_TEACHER`), or "" for none.
      teacher_overrides: config -> the `key=value` overrides of a teacher named by preset.
    """

    teacher: Callable[[Any], str]
    teacher_overrides: Callable[[Any], Sequence[str]]


@dataclasses.dataclass(frozen=True)
class Learner:
    """One learner as the runner sees it.

    Attributes:
      config_class: its run config, a `RunConfig` subclass.
      make_trainer: (config, env=None, env_params=None) -> `Trainer`; `env`, `env_params` replace the config's.
      warm_start: (the new run's config, the trained run's config, fresh learner state, trained learner state,
        index [O], shift [O]) -> the fresh state with the trained networks (and whatever else carries over), the new
        observation's input o read from the trained one's input index[o] (−1: none), reading shift[o] more
        (`Env.observation_source_index`, `Env.observation_source_shift`); None where the learner has no warm start.
      teaching: how its config names a teacher (`Teaching`); None where the learner cannot be taught.
      one_process_per_gpu: measured faster as one process per GPU than as one process driving them all (on MJX
        Warp, BENCHMARKS.md#devices), so a run of it starts them by itself (without a teacher: distillation has not
        been measured so); off, it takes several processes only where asked.
    """

    config_class: type[RunConfig]
    make_trainer: Callable[..., Trainer]
    warm_start: Callable[[Any, Any, Any, Any, np.ndarray, np.ndarray], Any] | None = None
    teaching: Teaching | None = None
    one_process_per_gpu: bool = False


LEARNERS: dict[str, Learner] = {
    "ppo": Learner(
        ppo.PPOConfig,
        ppo.make_trainer,
        warm_start=ppo_warm_start,
        teaching=Teaching(
            teacher=lambda config: config.teacher, teacher_overrides=lambda config: config.teacher_overrides
        ),
        one_process_per_gpu=True,
    ),
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


def teacher_of(config: RunConfig) -> str:
    """`config`'s teacher (`Teaching.teacher`), or "" where it has none or its learner cannot be taught."""
    teaching = learner_for(config).teaching
    return "" if teaching is None else teaching.teacher(config)


def teacher_overrides_of(config: RunConfig) -> tuple[str, ...]:
    """The overrides of `config`'s teacher named by preset (`Teaching.teacher_overrides`); () for none."""
    teaching = learner_for(config).teaching
    return () if teaching is None else tuple(teaching.teacher_overrides(config))


def make_trainer(config: RunConfig, **extras: Any) -> Trainer:
    """The trainer of the learner `config` configures, on the config's env; `extras` go to the learner's own
    `make_trainer` (the loaded `teacher` of a learner that can be taught)."""
    return learner_for(config).make_trainer(config, **extras)
