"""Teachers: a finished run's deterministic policy as the labeller of a learner that is taught (distillation).

Any learner can teach (its `Trainer.act`); one that can be taught says where its config names the teacher in the
learner registry (`jaxarm.agents.registry.Teaching`). PPO's student drives its own rollouts (DAgger: it is
labelled where it goes, not where the teacher would have gone), and every observation of a rollout is labelled
with the teacher's action inside the same compiled update (`PPOConfig.teacher`, `imitation_coef`,
`imitation_only`, `imitation_decay_updates`). A teacher reads the observation's privileged part where it has one (a
state policy teaching a camera policy), else the observation itself. A teacher run is loaded by the runner
(`jaxarm.runner.learners.make_trainer`), which knows every learner through the registry. A teacher named by preset
(`teacher=preset:NAME`) is trained by the runner first, into the student's run directory; `teacher=init_from` is
the run the student warm-starts from (kickstarting). Nothing here knows one learner.
"""

from collections.abc import Callable, Mapping

import jax

from jaxarm.envs import Observation
from jaxarm.envs.observation import PRIVILEGED

PRESET_TEACHER = "preset:"
"""How a teacher setting (`PPOConfig.teacher`) names a preset to train as the teacher (`preset:NAME`) instead of
a run directory."""

WARM_START_TEACHER = "init_from"
"""The teacher setting (`PPOConfig.teacher=init_from`) that names the run the student warm-starts from
(`RunConfig.init_from`, a run directory or the run's warm_start/ stage) as its teacher."""

Teacher = Callable[[Observation], jax.Array]
"""Observations [N, ...] -> the teacher's deterministic actions [N, A]."""


def teacher_preset_name(teacher: str) -> str | None:
    """The preset a teacher setting (`PPOConfig.teacher`) names (`preset:NAME` -> NAME; `preset:` alone -> ""), or
    None for a run directory or no teacher."""
    return teacher.removeprefix(PRESET_TEACHER) if teacher.startswith(PRESET_TEACHER) else None


def teacher_input(obs: Observation) -> Observation:
    """What a teacher reads of observations [N, ...]: their privileged part where they have one, else all."""
    if isinstance(obs, Mapping) and PRIVILEGED in obs:
        return obs[PRIVILEGED]
    return obs


def learner_as_teacher(trainer, state) -> Teacher:
    """The deterministic policy of a learner's `state` (its `trainer.act`) as a teacher, reading `teacher_input` of
    the student's observations: obs [N, ...] -> actions [N, A]; the state's arrays become constants of the program
    that calls it."""
    return lambda obs: trainer.act(state, teacher_input(obs))
