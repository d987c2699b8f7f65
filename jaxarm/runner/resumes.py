"""What a resumed run may change, checked against the run directory (rundir.py): the config keys a resume may
override, an edit of config.json since the latest checkpoint, a budget below what was done; and the records a
resume leaves (resumes.jsonl, and checkpoints/config.json, the config each checkpoint was trained with).
"""

import dataclasses
import json
import pathlib
import time
from collections.abc import Sequence

from jaxarm.agents.common.config import RunConfig, apply_overrides
from jaxarm.runner.rundir import RunDirError, any_checkpoint_files, read_config, write_config, write_json

RESUMABLE_KEYS = ("total_env_steps", "checkpoint_every_updates", "eval_every_updates", "eval_episodes")
"""Config fields a resumed run may change (`resume(run_dir, ["key=value"])`): they set how long the run goes on,
how often it is saved and evaluated, and how, but neither the compiled update nor what it computes.
`eval_env_params.NAME` may change too. `total_env_steps` only where the learner's schedule does not depend on it
(`RunConfig.budget_shapes_updates`)."""


def check_resumable(config: RunConfig, key: str, changer: str = "a resumed run") -> None:
    """RunDirError, saying that `changer` cannot change it and what a resume may change, unless a resumed run of
    `config` may change the config key `key` (a field, or `eval_env_params.NAME`)."""
    allowed = [*RESUMABLE_KEYS, "eval_env_params.NAME"]
    if key == "eval_env_params" or key.startswith("eval_env_params."):
        return
    if key not in RESUMABLE_KEYS:
        raise RunDirError(
            f"{changer} cannot change {key!r}: it would change the compiled learner or what it computes; "
            f"a resumed run may change {', '.join(allowed)}"
        )
    if key == "total_env_steps" and config.budget_shapes_updates:
        raise RunDirError(
            f"{changer} cannot change total_env_steps of this run: its {config.budget_shapes_updates} follows "
            "the budget set at the start; start a new run (init_from=RUN warm-starts it)"
        )


def apply_resume_overrides(config: RunConfig, overrides: Sequence[str]) -> RunConfig:
    """`config` with the `key=value` overrides a resumed run may take; RunDirError listing those for any other,
    once each override is known to be one (ValueError: `=3` was refused as "cannot change ''")."""
    updated = apply_overrides(config, overrides, validate=False)
    for item in overrides:
        check_resumable(config, item.partition("=")[0])
    updated.validate()
    return updated


def check_budget(config: RunConfig, done_updates: int) -> None:
    """RunDirError when `config`'s budget is below the `done_updates` a resumed run has already done."""
    if config.num_updates < done_updates:
        done = done_updates * config.env_steps_per_update
        raise RunDirError(
            f"total_env_steps={config.total_env_steps:,} is below the {done:,} env steps this run has done "
            f"({done_updates:,} updates); give at least {done:,}, or start a new run"
        )


def check_config_unedited(run_dir: pathlib.Path, config: RunConfig) -> str | None:
    """RunDirError when `config` (run_dir's config.json) differs from the config of the latest checkpoint in a
    field a resume may not change (`check_resumable`). Where the run has checkpoints but that record is missing,
    nothing can be checked: returns a warning saying so, in one line (refusing would stop a run whose record a kill
    between its first checkpoint and the record left missing); else None."""
    record = run_dir / "checkpoints" / "config.json"
    if not record.exists():
        if not any_checkpoint_files(run_dir):
            return None  # a run that starts afresh: no checkpoint to hold its config to
        return (
            f"{record}, the config of the latest checkpoint, is missing: an edit of {run_dir / 'config.json'} "
            "since then cannot be checked; resuming with config.json as it is"
        )
    try:
        saved, _ = read_config(run_dir, record)
    except ValueError:
        # Damaged with its checkpoints: restoring them says what is wrong.
        return None
    changed = [
        field.name for field in dataclasses.fields(config) if getattr(config, field.name) != getattr(saved, field.name)
    ]
    for name in changed:
        check_resumable(
            config, name, f"editing {run_dir / 'config.json'} ({name} was {getattr(saved, name)!r} at the checkpoint)"
        )
    return None


def record_resume(run_dir: pathlib.Path, config: RunConfig, preset: str, overrides: Sequence[str], update: int) -> None:
    """Writes the overridden config to config.json and appends the overrides to resumes.jsonl."""
    row = {"time": time.strftime("%Y-%m-%dT%H:%M:%S"), "resumed_at_update": update, "overrides": list(overrides)}
    with (run_dir / "resumes.jsonl").open("a") as log:
        log.write(json.dumps(row) + "\n")
    write_config(run_dir, config, preset)


def record_checkpoint_config(run_dir: pathlib.Path) -> None:
    """Copies config.json into checkpoints/, after a checkpoint is saved: the config its state was trained with."""
    write_json(run_dir / "checkpoints" / "config.json", json.loads((run_dir / "config.json").read_text()))
