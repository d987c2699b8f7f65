"""A run's gated tries (`RunConfig.retry_below`, `retry_at_env_steps`, `tries`): the gate a try's evaluations must
pass, and where a try that failed it is set aside (`tries/K/` of the run directory) before the next starts. The run
loop (loop.py) starts the tries, the chunk loop (chunks.py) applies the gate."""

import pathlib

import numpy as np

from jaxarm.agents.common.config import RunConfig

TRIES_DIR = "tries"
"""Where a run with a gate sets aside each try that failed it, as `tries/K/`."""
TRY_FILES = ("metrics.jsonl", "tensorboard", "checkpoints", "best", "best.json")
"""What a failed try leaves, set aside under `tries/K/`; its config, provenance and resumes stay the run's."""


class TryFailed(RuntimeError):
    """A try of a run with a gate (`RunConfig.retry_below`) had not reached it by `retry_at_env_steps`: its best
    evaluation's success rate was `best` after `env_steps`, and the run had trained `wall_time` seconds in all."""

    def __init__(self, best: float, env_steps: int, wall_time: float):
        super().__init__(f"best evaluation {best:.1%} after {env_steps:,} env steps")
        self.wall_time = wall_time


def failed_gate(config: RunConfig, best: dict | None, env_steps: int) -> bool:
    """Whether a try whose best evaluation so far is `best` has failed the config's gate after `env_steps`: at or
    past `retry_at_env_steps` and below `retry_below`. The best evaluation only rises, so a try that passed at its
    first evaluation past the gate passes at every later one, and on resume."""
    return env_steps >= config.retry_at_env_steps and (best is None or best["success_rate"] < config.retry_below)


def gated(config: RunConfig, try_index: int) -> bool:
    """Whether try `try_index` (from 0) must pass the config's gate: every try but the last, where it has one."""
    return bool(config.retry_below) and try_index < config.tries - 1


def tries_set_aside(run_dir: pathlib.Path) -> int:
    """How many tries of the run in `run_dir` failed its gate and were set aside: the index of the try it is in."""
    directory = run_dir / TRIES_DIR
    return sum(path.name.isdigit() for path in directory.iterdir()) if directory.is_dir() else 0


def warm_start_seed(seed: int, try_index: int) -> int:
    """The seed of try `try_index`'s warm-start stage in a run that trains it again for each try
    (`RunConfig.retry_warm_start`): the run's own for the first try, then one drawn from (seed, try) by numpy's
    `SeedSequence`, below 2**31, so that each try's first stage has randomness of its own."""
    if try_index == 0:
        return seed
    return int(np.random.SeedSequence([seed, try_index]).generate_state(1)[0] >> 1)


def set_aside_try(run_dir: pathlib.Path, stages: tuple[str, ...] = ()) -> pathlib.Path:
    """Moves what the current try of the run in `run_dir` wrote (`TRY_FILES`, and the stage directories `stages` its
    next try trains again) to `tries/K/`, K its index, and returns that folder; the run's config, provenance and
    other stages stay."""
    folder = run_dir / TRIES_DIR / str(tries_set_aside(run_dir))
    folder.mkdir(parents=True)
    for name in (*TRY_FILES, *stages):
        if (run_dir / name).exists():
            (run_dir / name).replace(folder / name)
    return folder
