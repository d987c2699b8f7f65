"""The chunk loop: chunks of compiled updates (programs.py) and, between them, the NaN stop, metric rows
(runlog.py), evaluations and the best state, checkpoints, the time limit and stop requests (signals.py). Where a
run starts and how it ends is the run loop's (loop.py)."""

import contextlib
import dataclasses
import json
import pathlib
import time
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.trainer import Trainer
from jaxarm.runner import metrics_log, processes, resumes, rundir
from jaxarm.runner.options import Options
from jaxarm.runner.programs import ChunkRunners, Evaluators, eval_key
from jaxarm.runner.runlog import RunLog, metric_rows
from jaxarm.runner.signals import StopRequests
from jaxarm.runner.tries import TryFailed, failed_gate, failed_train_gate, gated


class TrainingDiverged(RuntimeError):
    """NaN or inf appeared in the metrics or the learner state."""


class TrainingInterrupted(RuntimeError):
    """Ctrl-C or SIGTERM stopped training at a chunk end, after a checkpoint; the message says how to go on."""


@dataclasses.dataclass
class Start:
    """Where a run starts: its learner state (placed on the devices), updates done, wall seconds already spent,
    the best evaluation so far, and the index of its try (`RunConfig.retry_below`; 0 for the first, and for every
    run without a gate)."""

    state: Any
    done_updates: int
    wall_offset: float
    best: dict | None
    try_index: int = 0


def train_chunks(
    trainer: Trainer,
    config: RunConfig,
    run_dir: pathlib.Path,
    options: Options,
    start: Start,
    runners: ChunkRunners,
    evaluators: Evaluators,
) -> tuple[Any, int, float]:
    """Runs chunks of updates (`runners`) from `start` until the budget, the time limit or a stop request,
    logging, evaluating (`evaluators.nominal`) and checkpointing between them; returns (learner state, updates
    done, wall seconds of training in all, earlier segments included)."""
    hparams = config.hparams()
    primary = processes.is_primary()
    key = eval_key(config)
    checkpoints = run_dir / "checkpoints"
    state, done_updates, best = start.state, start.done_updates, start.best
    last_saved = done_updates
    clock = time.perf_counter()
    stop = StopRequests()
    steps_per_update = trainer.env_steps_per_update
    gate = gated(config, start.try_index)
    with contextlib.ExitStack() as stack:
        stack.enter_context(stop.installed())
        log = RunLog(stack, run_dir, trainer, options.wandb, done_updates, start.try_index) if primary else None
        while done_updates < trainer.num_updates:
            count = min(config.updates_per_chunk, trainer.num_updates - done_updates)
            runner = runners(count)
            chunk_start = time.perf_counter()
            try:
                state, metrics = runner(state, hparams)
                flat = metrics_log.flatten_metrics(jax.device_get(metrics))
            except jax.errors.JaxRuntimeError as error:  # raised in the program: an env's host check, Warp's launch
                rundir.resumable(error, run_dir)
                raise
            chunk_time = time.perf_counter() - chunk_start
            check_finite(flat, state, done_updates, count, checkpoints)
            rows = list(
                metric_rows(
                    flat,
                    done_updates,
                    steps_per_update,
                    start.wall_offset + time.perf_counter() - clock,
                    count * steps_per_update / chunk_time,
                )
            )
            evaluated = crossed(config.eval_every_updates, done_updates, done_updates + count)
            if evaluated:
                best = evaluate(evaluators, state, key, rows[-1], best, done_updates + count, run_dir)
            done_updates += count
            if log:
                log.write(rows, done_updates * steps_per_update, flat)
            failed = gate_failure(config, run_dir, best if evaluated else None, rows) if gate else None
            # Agreed by every process, as the stops below are; a run without a gate asks nobody.
            if gate and processes.any_process(failed is not None):
                raise TryFailed(failed or "another process's gate")
            out_of_time = options.out_of_time()
            # Agreed by every process: one that stopped alone would leave the others waiting in a collective.
            out_of_time, stopping = processes.any_process(out_of_time), processes.any_process(stop.requested)
            if (
                done_updates - last_saved >= config.checkpoint_every_updates
                or done_updates == trainer.num_updates
                or out_of_time
                or stopping
            ):
                save(checkpoints, done_updates, state, run_dir)
                if primary:
                    resumes.record_checkpoint_config(run_dir)
                last_saved = done_updates
            if options.on_chunk:
                options.on_chunk(done_updates)
            if stopping:
                raise rundir.resumable(
                    TrainingInterrupted(
                        f"interrupted: checkpoint at update {done_updates} of {trainer.num_updates} saved in "
                        f"{checkpoints}; resume the run to continue"
                    ),
                    run_dir,
                )
            if out_of_time:
                break
    return state, done_updates, start.wall_offset + time.perf_counter() - clock


def gate_failure(config: RunConfig, run_dir: pathlib.Path, evaluated: dict | None, rows: list[dict]) -> str | None:
    """How the try in `run_dir` failed a gate at the end of a chunk (its metric `rows`, one per update, written),
    None where it did not: the evaluation's gate where the chunk ended in an evaluation (`evaluated`: the best so
    far), the training episodes' where the chunk crossed `retry_train_at_env_steps`. Only the primary process keeps
    the metrics that gate reads (resumed or not): the others pass it, and follow the primary's word."""
    env_steps = rows[-1]["env_steps"]
    if evaluated is not None and (failed := failed_gate(config, evaluated, env_steps)):
        return failed
    chunk_start = rows[0]["env_steps"] - rows[0]["env_steps"] // rows[0]["updates"]
    crossing = config.retry_train_below and chunk_start < config.retry_train_at_env_steps <= env_steps
    if not (crossing and processes.is_primary()):
        return None
    window = metrics_log.read_metrics(run_dir)[-config.updates_per_time_limit() :]
    return failed_train_gate(config, window, env_steps)


def evaluate(
    evaluators: Evaluators, state, key: jax.Array, row: dict, best: dict | None, updates: int, run_dir: pathlib.Path
) -> dict | None:
    """Evaluates `state` (after `updates`) into its chunk's last `row`; a state better than `best` is saved under
    run_dir/best with its evaluation (best.json). Returns the best evaluation so far."""
    result = evaluators.nominal(state, key)
    row.update({f"eval/{name}": value for name, value in result.items() if isinstance(value, float)})
    if better(result, best):
        best = {"updates": updates, **result}
        save(run_dir / "best", updates, state, run_dir)
        if processes.is_primary():
            rundir.write_json(run_dir / "best.json", best)
    return best


def read_best(run_dir: pathlib.Path) -> dict | None:
    """The best evaluation so far (run_dir/best.json), None before the first; RunDirError naming the file where it
    is damaged or edited (a resume took `null` for none, and a worse state replaced best/)."""
    path = run_dir / "best.json"
    if not path.exists():
        return None
    try:
        best = json.loads(path.read_text())
        if not isinstance(best, dict) or not all(isinstance(best.get(name), (int, float)) for name in SCORES):
            raise TypeError(f"no {' and '.join(SCORES)} numbers")
    except (ValueError, TypeError) as error:  # ValueError: JSONDecodeError, UnicodeDecodeError
        raise rundir.damaged(path, error) from None
    return best


def crossed(multiple: int, before: int, after: int) -> bool:
    """Whether a multiple of `multiple` (> 0) lies in (before, after]: cadences that do not move on resume."""
    return multiple > 0 and after // multiple > before // multiple


SCORES = ("success_rate", "return_mean")
"""What ranks evaluations, in order (`better`)."""


def better(result: dict, best: dict | None) -> bool:
    """Whether an evaluation beats the best so far: higher success rate, then higher mean return."""
    return best is None or tuple(result[name] for name in SCORES) > tuple(best[name] for name in SCORES)


def save(directory: pathlib.Path, step: int, state, run_dir: pathlib.Path) -> None:
    """`checkpoint.save`, with what to do next added to its error (free space, then resume)."""
    try:
        checkpoint.save(directory, step, state)
    except checkpoint.CheckpointError as error:
        raise rundir.resumable(
            checkpoint.CheckpointError(f"{error}; fix that, then resume the run to continue"), run_dir
        ) from error


def check_finite(flat: dict[str, np.ndarray], state, done_updates: int, count: int, checkpoints: pathlib.Path) -> None:
    """TrainingDiverged where a chunk of `count` updates after `done_updates` left NaN or inf in its metrics
    (`flat`) or in the learner state."""
    bad = first_non_finite(flat)
    if bad is not None or not state_is_finite(state):
        raise TrainingDiverged(diverged_message(bad, done_updates, count, checkpoints))


def first_non_finite(flat_metrics: dict[str, np.ndarray]) -> tuple[int, str] | None:
    """(index within the chunk, metric name) of the first NaN/inf, or None."""
    found = [
        (int(np.argmax(~np.isfinite(values))), name)
        for name, values in flat_metrics.items()
        if not np.all(np.isfinite(values))
    ]
    return min(found) if found else None


@jax.jit
def _all_finite(state) -> jax.Array:
    leaves = [leaf for leaf in jax.tree.leaves(state) if jnp.issubdtype(leaf.dtype, jnp.floating)]
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(leaf)) for leaf in leaves]))


def state_is_finite(state) -> bool:
    """Whether every float of `state` is finite; computed where the state lives (on every device, in every
    process), so that only one bool comes back."""
    return bool(_all_finite(state))


def diverged_message(bad: tuple[int, str] | None, done_updates: int, count: int, checkpoints: pathlib.Path) -> str:
    """Where NaN/inf appeared (`bad`: index in the chunk and metric, or None when only the state shows it) and
    what is kept."""
    where = (
        f"update {done_updates + bad[0] + 1} ({bad[1]})"
        if bad
        else f"updates {done_updates + 1}-{done_updates + count}"
    )
    latest = checkpoint.latest_step(checkpoints)
    if latest is None:
        return (
            f"NaN or inf at {where}; training stopped before its first checkpoint, so there is nothing to keep. "
            "Change the config and start again (training into the same directory starts afresh)."
        )
    return (
        f"NaN or inf at {where}; training stopped. The last good checkpoint (update {latest}) in {checkpoints} "
        "is intact."
    )
