"""A run's gated tries (`RunConfig.retry_below`, `retry_at_env_steps`, `tries`; the earlier gate on training
episodes, `retry_train_below` at `retry_train_at_env_steps`): the gates a try must pass, and where a try that failed
one is set aside (`tries/K/` of the run directory) before the next starts. The run loop (loop.py) starts the tries,
the chunk loop (chunks.py) applies the gates."""

import pathlib

import numpy as np

from jaxarm.agents.common.config import RunConfig

TRIES_DIR = "tries"
"""Where a run with a gate sets aside each try that failed it, as `tries/K/`."""
TRY_FILES = ("metrics.jsonl", "tensorboard", "checkpoints", "best", "best.json")
"""What a failed try leaves, set aside under `tries/K/`; its config, provenance and resumes stay the run's."""


class TryFailed(RuntimeError):
    """A try of a run with a gate (`RunConfig.retry_below`) failed one: the message says which gate and by how
    much."""


def failed_gate(config: RunConfig, best: dict, env_steps: int) -> str | None:
    """How a try whose best evaluation so far, just evaluated, is `best` has failed the config's gate after
    `env_steps`, None where it has not: at or past `retry_at_env_steps` and below `retry_below`. The best evaluation
    only rises, so a try that passed at its first evaluation past the gate passes at every later one, and on
    resume."""
    if env_steps < config.retry_at_env_steps or best["success_rate"] >= config.retry_below:
        return None
    return (
        f"best evaluation {best['success_rate']:.1%} after {env_steps:,} env steps; it asks {config.retry_below:.0%} "
        f"by {config.retry_at_env_steps:,}"
    )


def training_success(rows: list[dict]) -> float:
    """The share of the training episodes of metrics `rows` that succeeded: each row's `episodes/success_rate`
    weighted by its `episodes/judged` (0 where none was judged)."""
    judged = sum(row["episodes/judged"] for row in rows)
    return sum(row["episodes/success_rate"] * row["episodes/judged"] for row in rows) / max(judged, 1.0)


def failed_train_gate(config: RunConfig, rows: list[dict], env_steps: int) -> str | None:
    """How a try failed the config's gate on training episodes (`retry_train_below`), None where it has not:
    `rows` are its metrics of the last time limit of updates to `env_steps` (every env's last episode there at
    least: a shorter span may see the failures, which end together at the time limit, or miss them)."""
    rate = training_success(rows)
    if rate >= config.retry_train_below:
        return None
    return (
        f"training episodes {rate:.2%} over the {len(rows)} updates to {env_steps:,} env steps; it asks "
        f"{config.retry_train_below:.2%} by {config.retry_train_at_env_steps:,}"
    )


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
