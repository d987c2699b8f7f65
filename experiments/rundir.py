"""A run directory: its config, metrics log, checkpoints and evaluation, shared by run, eval and sweep.

Layout of `runs/<config>-<timestamp>/`:
  config.json      the resolved config (with "preset", and "agent": the learner's name in jaxarm.agents.registry)
  metrics.jsonl    one JSON row per update
  tensorboard/     TensorBoard event files
  checkpoints/     orbax checkpoints of the whole learner state, named by update count
  curve.png        learning curve
  eval.json        deterministic evaluation of the final policy
"""

import dataclasses
import json
import pathlib
import time
import typing
from collections.abc import Callable
from typing import Any

import jax
import numpy as np

from jaxarm.agents import registry
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.evaluate import evaluate


def new_run_dir(preset: str, root: str = "runs") -> pathlib.Path:
    return pathlib.Path(root) / f"{preset}-{time.strftime('%Y%m%d-%H%M%S')}"


def _as_tuples(value):
    return tuple(_as_tuples(item) for item in value) if isinstance(value, list) else value


def write_config(run_dir: pathlib.Path, config: RunConfig, preset: str) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    data = {"preset": preset, "agent": registry.name_of(config), **dataclasses.asdict(config)}
    (run_dir / "config.json").write_text(json.dumps(data, indent=2))


def read_config(run_dir: pathlib.Path) -> tuple[RunConfig, str]:
    """The config saved in `run_dir` (validated) and its preset name; ValueError if missing, unreadable or invalid."""
    path = run_dir / "config.json"
    if not path.exists():
        raise ValueError(f"{run_dir} is not a run directory: no config.json")
    try:
        data = json.loads(path.read_text())
        preset, agent = data.pop("preset"), data.pop("agent")
        cls = registry.get(agent).config_class
        hints = typing.get_type_hints(cls)
        fields = {
            name: _as_tuples(value) if typing.get_origin(hints[name]) is tuple else value
            for name, value in data.items()
        }
        config = cls(**fields)
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{path} is corrupt or from another version: {error}") from None
    config.validate()
    return config, preset


def restore_state(run_dir: pathlib.Path, trainer, config: RunConfig):
    """The latest checkpointed learner state of `run_dir` (CheckpointError if none or mismatched)."""
    like = jax.eval_shape(trainer.init, jax.random.PRNGKey(config.seed), config.hparams())
    return checkpoint.restore(run_dir / "checkpoints", like)


def warm_starter(config: RunConfig) -> Callable[[Any], Any]:
    """fresh learner state -> the same warm-started from the latest checkpoint of the run in `config.init_from`,
    by the learner's own warm start (`jaxarm.agents.registry.Learner.warm_start`). ValueError or CheckpointError
    when that run cannot serve."""
    source_dir = pathlib.Path(config.init_from)
    source, _ = read_config(source_dir)
    learner = registry.learner_for(config)
    warm_start = learner.warm_start
    if warm_start is None or registry.learner_for(source) is not learner:
        with_warm_starts = [name for name, each in registry.LEARNERS.items() if each.warm_start is not None]
        raise ValueError(
            f"init_from: warm starts exist for {', '.join(with_warm_starts)} only, from a run of the same learner "
            f"({source_dir} is {registry.name_of(source)}, this run {registry.name_of(config)})"
        )
    trained = restore_state(source_dir, learner.make_trainer(source), source)
    index = config.make_env()[0].observation_source_index(source.make_env()[0])
    return lambda state: warm_start(state, trained, index)


def evaluate_state(trainer, config: RunConfig, state, episodes: int, seed: int) -> dict:
    """Deterministic-policy results on `episodes` fresh episodes, as a JSON-ready dict."""
    env, env_params = config.make_eval_env()
    run = jax.jit(lambda learner, key: evaluate(env, env_params, lambda obs: trainer.act(learner, obs), key, episodes))
    result = run(state, jax.random.PRNGKey(seed)).summary()
    return {**result, "device": jax.devices()[0].device_kind}


def write_json(path: pathlib.Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=2))


def read_metrics(run_dir: pathlib.Path) -> list[dict]:
    path = run_dir / "metrics.jsonl"
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def truncate_metrics(run_dir: pathlib.Path, max_update: int) -> None:
    """Drops metric rows after `max_update` (rows a killed run logged past its last checkpoint)."""
    rows = [row for row in read_metrics(run_dir) if row["updates"] <= max_update]
    (run_dir / "metrics.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))


def flatten_metrics(metrics, prefix: str = "") -> dict[str, np.ndarray]:
    """A (nested) flax struct of arrays [K] -> {"episodes/return_mean": array [K], ...}."""
    if not dataclasses.is_dataclass(metrics):
        return {prefix.rstrip("/"): np.asarray(metrics)}
    flat = {}
    for field in dataclasses.fields(metrics):
        flat.update(flatten_metrics(getattr(metrics, field.name), f"{prefix}{field.name}/"))
    return flat
