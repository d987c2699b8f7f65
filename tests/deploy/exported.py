"""A sorter run directory holding an exported random policy, for the CLIs that drive exports (transfer, rehearse)."""

import dataclasses
import pathlib

import numpy as np

from experiments import configs
from experiments.benchmarks.deploy import random_policy
from jaxarm.agents.common.config import RunConfig
from jaxarm.export import origin
from jaxarm.runner import rundir


def sorter_run(run_dir: pathlib.Path, max_episode_steps: int) -> RunConfig:
    """`ppo_sorter_dr` with episodes of `max_episode_steps`, written as the run in `run_dir` (nothing exported)."""
    config = configs.get("ppo_sorter_dr")
    config = dataclasses.replace(config, env_params=(*config.env_params, ("max_episode_steps", max_episode_steps)))
    rundir.write_config(run_dir, config, "ppo_sorter_dr")
    return config


def export_random_policy(run_dir: pathlib.Path, config: RunConfig, update: str) -> None:
    """A random state policy of `config`'s sizes as `run_dir`'s export, recorded as from checkpoint `update`."""
    env, _ = config.make_eval_env()
    policy = random_policy(config, env.spec.observation_shape[0], env.spec.action_shape[0], np.random.default_rng(0))
    (run_dir / "export").mkdir()
    policy.save(run_dir / "export" / "policy.npz")
    rundir.write_json(run_dir / "export" / origin.FILE, origin.record(update))
