"""Teacher-student distillation: a finished run's deterministic policy as the regression target of PPO's policy.

The student drives its own rollouts (DAgger: it is labelled where it goes, not where the teacher would have gone),
and every observation of a rollout is labelled with the teacher's action inside the same compiled update
(`PPOConfig.teacher`, `imitation_coef`, `imitation_only`). A teacher reads the observation's privileged part
where it has one (a state policy teaching a camera policy), else the observation itself.
"""

import pathlib
from collections.abc import Callable, Mapping

import jax

from jaxarm.envs import Observation
from jaxarm.envs.observation import PRIVILEGED

Teacher = Callable[[Observation], jax.Array]
"""Observations [N, ...] -> the teacher's deterministic actions [N, A]."""


def teacher_input(obs: Observation) -> Observation:
    """What a teacher reads of observations [N, ...]: their privileged part where they have one, else all."""
    if isinstance(obs, Mapping) and PRIVILEGED in obs:
        return obs[PRIVILEGED]
    return obs


def load_teacher(run_dir: pathlib.Path) -> Teacher:
    """The deterministic policy of the run in `run_dir` (its latest checkpoint), reading `teacher_input`; its
    arrays become constants of the program that calls it. RunDirError or CheckpointError for a run that cannot
    be read."""
    # The runner imports every learner (agents.registry): imported here, when a teacher is loaded, not with PPO.
    from jaxarm.agents import registry
    from jaxarm.runner.rundir import read_config, restore_state

    config, _ = read_config(run_dir)
    trainer = registry.make_trainer(config)
    state = restore_state(run_dir, trainer, config)
    return lambda obs: trainer.act(state, teacher_input(obs))
