"""The training loop: chunks of compiled updates, and between chunks metrics, progress, NaN stop, evaluation and
checkpoints, into a run directory (rundir.py). `python -m experiments.run` is a thin CLI over `train` and
`resume`; notebooks and scripts call them directly.

The learner is compiled in chunks of `updates_per_chunk` updates; between chunks the loop logs metrics (JSON
lines, TensorBoard, optionally wandb), shows progress, checks for NaN/inf, evaluates (`eval_every_updates`)
and checkpoints the whole learner state. A resumed run continues from the latest checkpoint; on CPU the result
is bit-identical to an uninterrupted run. Ctrl-C or SIGTERM stops at the next chunk end with a checkpoint.
A run whose teacher is named by preset (`teacher=preset:NAME`) has two stages: the teacher is trained (or resumed)
into `<run dir>/teacher`, then the student from it; a resumed run resumes the stage it stopped in.
With several devices the env batch is split across all of them (data parallel, jaxarm/agents/common/sharding.py),
and with several processes (`jax.distributed`) process 0 alone writes the run directory (processes.py).
"""

import contextlib
import dataclasses
import json
import os
import pathlib
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh

from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig, apply_overrides
from jaxarm.agents.common.sharding import data_mesh, envs_split_over, state_shardings
from jaxarm.agents.common.trainer import Trainer, make_chunk_runner
from jaxarm.agents.ppo.distill import teacher_input
from jaxarm.runner import learners, plots, processes, progress, rundir
from jaxarm.runner.sinks import Sink, TensorBoardSink, WandbOptions, WandbSink, wandb_run_id

FINAL_EVAL_SEED_OFFSET = 1_000_003
"""Evaluations during and at the end of training use key `seed + FINAL_EVAL_SEED_OFFSET`: the same episodes
each time, so evaluation rows compare checkpoints, not episode draws."""


class TrainingDiverged(RuntimeError):
    """NaN or inf appeared in the metrics or the learner state."""


class TrainingInterrupted(RuntimeError):
    """Ctrl-C or SIGTERM stopped training at a chunk end, after a checkpoint; the message says how to go on."""


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


def metric_rows(
    flat: dict[str, np.ndarray], first_update: int, env_steps_per_update: int, wall_time: float, steps_per_second: float
):
    """One JSON-ready row per update of a chunk: its count, env steps so far (a Python int, past int32 too), the
    chunk's wall clock and rate, and its metrics."""
    count = len(next(iter(flat.values())))
    for index in range(count):
        updates = first_update + index + 1
        row = {
            "updates": updates,
            "env_steps": updates * env_steps_per_update,
            "wall_time": wall_time,
            "steps_per_second": steps_per_second,
        }
        row.update({name: float(values[index]) for name, values in flat.items()})
        yield row


def crossed(multiple: int, before: int, after: int) -> bool:
    """Whether a multiple of `multiple` (> 0) lies in (before, after]: cadences that do not move on resume."""
    return multiple > 0 and after // multiple > before // multiple


def better(result: dict, best: dict | None) -> bool:
    """Whether an evaluation beats the best so far: higher success rate, then higher mean return."""
    return best is None or (result["success_rate"], result["return_mean"]) > (best["success_rate"], best["return_mean"])


class StopRequests:
    """Ctrl-C (SIGINT) and SIGTERM, while installed, ask the loop to stop at the next chunk end; a second Ctrl-C
    ends the process at once with status 130, keeping the checkpoints saved so far. Installed only in the main
    thread (signals cannot be caught elsewhere). `aborted` ends the line said then (e.g. how to resume)."""

    def __init__(self, aborted: str = ""):
        self.requested = False
        self.aborted = aborted

    def _handle(self, signum, frame):
        if self.requested and signum == signal.SIGINT:
            print(
                f"\nSIGINT again: aborted; the checkpoints saved before are kept{self.aborted}",
                file=sys.stderr,
                flush=True,
            )
            # Not KeyboardInterrupt: unwinding while XLA compiles or runs on other threads printed a traceback
            # (rc -2, 3 of 3 tries during compilation) or segfaulted at interpreter exit (rc -11), and nothing is
            # left to clean up that a resume does not (rows past the last checkpoint dropped, TensorBoard's purged).
            os._exit(130)
        self.requested = True
        print(
            f"\n{signal.Signals(signum).name}: stopping at the next chunk end with a checkpoint "
            "(Ctrl-C again to abort now)",
            file=sys.stderr,
            flush=True,
        )

    @contextlib.contextmanager
    def installed(self) -> Iterator["StopRequests"]:
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        previous = {signum: signal.signal(signum, self._handle) for signum in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield self
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)


@dataclasses.dataclass(frozen=True)
class Options:
    """How a run is driven, beside its config (nothing here changes what it computes).

    Attributes:
      stop_after_s: checkpoint and stop after the first chunk that ends past this many seconds (resume later).
      wandb: also log to this wandb project; None for no wandb.
      on_chunk: called with the update count after each chunk's rows are logged (e.g. to watch a run).
      devices: the devices to split the env batch over; None for every device of every process.
      presets: preset name -> its config (`experiments.configs.get`): how a teacher named by preset
        (`teacher=preset:NAME`) is found, before it has been trained; the library holds no presets.
    """

    stop_after_s: float | None = None
    wandb: WandbOptions | None = None
    on_chunk: Callable[[int], None] | None = None
    devices: Sequence[jax.Device] | None = None
    presets: Callable[[str], RunConfig] | None = None


def train(
    config: RunConfig, run_dir: pathlib.Path, *, preset: str = "custom", resume: bool = False, options=Options()
) -> dict:
    """Trains `config` into `run_dir` and returns the final evaluation (also written to eval.json).

    With `resume`, continues from the directory's latest checkpoint (a directory with none starts afresh).
    Without, the directory must be new, empty, or hold a run that never reached its first checkpoint. Raises
    rundir.RunDirError (foreign files, in use, already a run), TrainingDiverged on NaN/inf, TrainingInterrupted
    after Ctrl-C or SIGTERM; with `options.stop_after_s`, the first chunk past it is checkpointed and the
    evaluation describes that state. With several processes (`jax.distributed`) every process calls this with
    the same arguments; process 0 alone writes the directory (processes.py). A teacher named by preset
    (`teacher=preset:NAME`, found through `options.presets`) is trained first, into `run_dir/teacher`
    (`_train_teacher`); a time limit counts both stages.
    """
    run_dir = pathlib.Path(run_dir)
    rundir.check_holds_a_run_or_nothing(run_dir)
    with _locked_by_primary(run_dir):
        return _train_locked(config, preset, run_dir, resume, options)


def resume(run_dir: pathlib.Path, overrides: Sequence[str] = (), options=Options()) -> tuple[dict, RunConfig]:
    """Continues the run in `run_dir` from its latest checkpoint with the `key=value` overrides a resumed run may
    take (rundir.RESUMABLE_KEYS; recorded in config.json and resumes.jsonl). Returns (evaluation, config). A run
    that has finished, resumed without overrides, is left as it is: its eval.json is returned."""
    run_dir = pathlib.Path(run_dir)
    # Checked before the lock writes anything: a directory that is no run, or overrides it may not take.
    config, preset = rundir.read_config(run_dir)
    unchecked = rundir.check_config_unedited(run_dir, config)
    config = rundir.apply_resume_overrides(config, list(overrides))
    with _locked_by_primary(run_dir):
        if unchecked and processes.is_primary():
            print(f"warning: {unchecked}", file=sys.stderr)
        finished = None if overrides else rundir.finished_evaluation(run_dir, config)
        if finished is not None:
            # Nothing asked: evaluating again would only rewrite eval.json (experiments.eval writes its own file).
            # A row a killed process half wrote past the end is still dropped, as every resume drops it.
            if processes.is_primary():
                rundir.truncate_metrics(run_dir, config.num_updates)
                print(
                    f"{run_dir} has finished its {config.num_updates:,} updates; nothing done. To train further, "
                    f"give a larger total_env_steps=N; to evaluate again, python -m experiments.eval {run_dir}",
                    file=sys.stderr,
                )
            return finished, config
        return _train_locked(config, preset, run_dir, True, options, list(overrides)), config


def _locked_by_primary(run_dir: pathlib.Path) -> contextlib.AbstractContextManager:
    """The run directory's lock, held by the process that writes it (processes.is_primary)."""
    return rundir.locked(run_dir) if processes.is_primary() else contextlib.nullcontext()


@dataclasses.dataclass
class _Start:
    """Where a run starts: its learner state (placed on the devices), updates done, wall seconds already spent,
    and the best evaluation so far."""

    state: Any
    done_updates: int
    wall_offset: float
    best: dict | None


def _train_locked(
    config: RunConfig, preset: str, run_dir: pathlib.Path, resume: bool, options: Options, overrides: Sequence[str] = ()
) -> dict:
    """`train`, with the lock held, after the teacher stage where there is one (the teacher's evaluation is
    returned where a time limit stopped that stage); a resume's `overrides` are recorded once its checkpoint is
    restored."""
    if rundir.teacher_preset(config):
        clock = time.perf_counter()
        stopped = _train_teacher(config, preset, run_dir, resume, options)
        if stopped is not None:
            return stopped
        if options.stop_after_s is not None:
            spent = time.perf_counter() - clock
            options = dataclasses.replace(options, stop_after_s=max(0.0, options.stop_after_s - spent))
    trainer = learners.make_trainer(config, run_dir)
    if processes.is_primary():
        progress.explain_slow_compiles(config.make_env(randomized=False)[0])
    run_steps = config.num_updates * config.env_steps_per_update
    if run_steps > config.total_env_steps and processes.is_primary():
        print(
            f"total_env_steps={config.total_env_steps:,} runs as {run_steps:,} env steps "
            f"(+{run_steps / config.total_env_steps - 1:.0%}): {config.num_updates:,} updates in whole chunks of "
            f"{config.chunk_updates:,}",
            file=sys.stderr,
        )
    evaluators = _Evaluators.of(trainer, config)
    mesh = data_mesh(options.devices)
    # Under the mesh, VmapEnv steps each device's envs on that device (jaxarm.envs.wrappers.over_env_batch). The
    # pool compiles the first chunk while the start state is made, and the evaluations while training runs;
    # leaving it waits for that.
    with envs_split_over(mesh), ThreadPoolExecutor(1, thread_name_prefix="compile") as compiling:
        resume = _resumes(run_dir, resume)
        like = state_like(trainer, config, mesh)
        resumed_at = (checkpoint.latest_step(run_dir / "checkpoints") or 0) if resume else 0
        runners = _ChunkRunners.ahead(trainer, config, like, resumed_at, compiling)
        start = _start(trainer, config, preset, run_dir, resume, overrides, like)
        state, done_updates, train_time = _train_chunks(
            trainer, config, run_dir, options, start, runners, evaluators, compiling
        )
        return _final_evaluation(trainer, config, preset, run_dir, state, done_updates, train_time, evaluators)


def state_like(trainer: Trainer, config: RunConfig, mesh: Mesh):
    """The learner state's shapes and dtypes (`jax.ShapeDtypeStruct`s), with its shardings on `mesh`."""
    like = jax.eval_shape(trainer.init, jax.random.PRNGKey(config.seed), config.hparams())
    return jax.tree.map(
        lambda leaf, sharding: jax.ShapeDtypeStruct(
            leaf.shape, leaf.dtype, sharding=sharding, weak_type=leaf.weak_type
        ),
        like,
        state_shardings(like, mesh),
    )


class _ChunkRunners:
    """The chunk programs (`make_chunk_runner`) by update count. The first chunk's program is traced and lowered
    before the start state is made, and compiled on a pool meanwhile: tracing and lowering hold the interpreter,
    compiling (or reading XLA's cache) lets it go. On one H200 a 2,048-env sorter run's first chunk ended
    0.3-3.1 s sooner (three pairs of runs). Other counts (a run's last, shorter chunk) compile at their first
    call."""

    def __init__(self, trainer: Trainer, shardings, ahead: dict[int, Future]):
        self._trainer, self._shardings, self._ahead = trainer, shardings, ahead
        self._programs: dict[int, Callable] = {}

    @classmethod
    def ahead(cls, trainer: Trainer, config: RunConfig, like, done_updates: int, pool: Executor) -> "_ChunkRunners":
        """Runners whose first chunk, after `done_updates`, compiles on `pool` for states like `like`."""
        count = min(config.updates_per_chunk, trainer.num_updates - done_updates)
        shardings = jax.tree.map(lambda leaf: leaf.sharding, like)
        if count < 1:  # nothing left to train: the run only evaluates
            return cls(trainer, shardings, {})
        lowered = make_chunk_runner(trainer, count, shardings).lower(like, config.hparams())
        return cls(trainer, shardings, {count: pool.submit(lowered.compile)})

    def __call__(self, count: int) -> Callable:
        if count not in self._programs:
            ahead = self._ahead.pop(count, None)
            self._programs[count] = (
                ahead.result() if ahead else make_chunk_runner(self._trainer, count, self._shardings)
            )
        return self._programs[count]


@dataclasses.dataclass(frozen=True)
class _Evaluators:
    """A run's evaluations, each one program: on the eval env (during training and at the end), and at the end
    under the config's randomised params where it has them."""

    nominal: learners.Evaluator
    randomized: learners.Evaluator | None

    @classmethod
    def of(cls, trainer: Trainer, config: RunConfig) -> "_Evaluators":
        randomized = (
            learners.make_evaluator(trainer, config, config.eval_episodes, randomized=True)
            if config.randomize
            else None
        )
        return cls(learners.make_evaluator(trainer, config, config.eval_episodes), randomized)

    def compile_ahead(self, pool: Executor, state, key: jax.Array) -> None:
        for evaluator in (self.nominal, self.randomized):
            if evaluator is not None:
                evaluator.compile_ahead(pool, state, key)


def _train_teacher(
    config: RunConfig, preset: str, run_dir: pathlib.Path, resuming: bool, options: Options
) -> dict | None:
    """Trains the teacher `config` names by preset into `run_dir/teacher`, or resumes it there, having first
    written the student's config.json, so that a run stopped in this stage resumes as the student's. Returns None
    once the teacher has finished (at once where it had), else its evaluation (stopped by `options.stop_after_s`).
    Bad names and mismatches raise ValueError before anything is written."""
    name = rundir.teacher_preset(config)
    teacher_dir = run_dir / rundir.TEACHER_DIR
    if (teacher_dir / "config.json").exists():
        teacher, trained_preset = rundir.read_config(teacher_dir)
        if trained_preset != name:
            raise rundir.RunDirError(
                f"{teacher_dir} holds a teacher trained from preset {trained_preset!r}, not {name!r}; use another "
                "run directory"
            )
        if rundir.finished_evaluation(teacher_dir, teacher) is not None:
            return None
        if not resuming and rundir.any_checkpoint_files(teacher_dir):
            raise rundir.resumable(
                rundir.RunDirError(f"{run_dir} already holds a run, in its teacher stage; resume it (resume=True)"),
                run_dir,
            )
    else:
        teacher = teacher_config(config, options.presets)
    if processes.is_primary():
        if not (run_dir / "config.json").exists():
            rundir.write_config(run_dir, config, preset)
        print(f"teacher stage: {name} into {teacher_dir}", file=sys.stderr)
    try:
        if (teacher_dir / "config.json").exists():
            result, _ = resume(teacher_dir, options=options)
        else:
            result = train(teacher, teacher_dir, preset=name, options=options)
    except Exception as error:
        # Resuming the student's run goes on with its teacher, and then with the student: point there.
        if getattr(error, "resume_dir", None) is not None:
            rundir.resumable(error, run_dir)
        raise
    if result["finished"]:
        return None
    if processes.is_primary():
        print(f"stopped in the teacher stage; resume {run_dir} to go on", file=sys.stderr)
    return result


def teacher_config(config: RunConfig, presets: Callable[[str], RunConfig] | None) -> RunConfig:
    """The config of the teacher `config` names by preset, with `teacher_overrides`; ValueError in one line for
    an unknown preset, a bad override, a teacher with a preset teacher of its own, or one that does not observe
    what this run's env gives a teacher (`jaxarm.agents.ppo.distill.teacher_input`)."""
    name = rundir.teacher_preset(config)
    if presets is None:
        raise ValueError(
            f"teacher=preset:{name}: give Options(presets=...) a lookup of presets (experiments.configs.get)"
        )
    try:
        teacher = apply_overrides(presets(name), getattr(config, "teacher_overrides", ()))
    except ValueError as error:
        raise ValueError(f"teacher=preset:{name}: {error}") from None
    if rundir.teacher_preset(teacher):
        raise ValueError(
            f"teacher=preset:{name} has a teacher preset of its own; train that run first and give teacher=RUN_DIR"
        )
    given = teacher_input(config.make_env(randomized=False)[0].spec.observation)
    observed = teacher.make_env(randomized=False)[0].spec.observation
    if given != observed:
        shapes = jax.tree.map(lambda part: part.shape, (given, observed))
        raise ValueError(
            f"teacher=preset:{name} observes {shapes[1]} but this run's env gives a teacher {shapes[0]} (a camera "
            "student's env needs env_kwargs.privileged=true)"
        )
    return teacher


def _resumes(run_dir: pathlib.Path, resume: bool) -> bool:
    """Whether the run in `run_dir` resumes from its latest checkpoint (`resume`), after checking that there is
    one to resume, or none where the run starts; a run that died before its first checkpoint starts afresh."""
    primary = processes.is_primary()
    has_run = (run_dir / "config.json").exists()
    restart = has_run and not rundir.any_checkpoint_files(run_dir)
    # Every process has looked before the primary clears anything.
    processes.wait_for_all("run directory read")
    if restart:
        # Died before its first checkpoint (Ctrl-C while compiling, NaN at once, a full disk), or while writing it
        # (a kill, a full disk): nothing to keep.
        if primary:
            unfinished = checkpoint.half_written(run_dir / "checkpoints")
            # A teacher stage writes config.json alone: then nothing of the student's own had begun.
            if unfinished or (run_dir / rundir.PROVENANCE_FILE).exists():
                why = f"only a half-written one, {', '.join(unfinished)}" if unfinished else "none"
                print(f"{run_dir} has no complete checkpoint ({why}): starting it afresh", file=sys.stderr)
            rundir.clear_run(run_dir)
        resume = False
    elif has_run and not resume:
        raise rundir.resumable(
            rundir.RunDirError(f"{run_dir} already holds a run; resume it (resume=True) or use another run directory"),
            run_dir,
        )
    elif resume and not has_run:
        raise rundir.RunDirError(f"{run_dir} is not a run directory: no config.json")
    return resume


def _start(
    trainer: Trainer,
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    resume: bool,
    overrides: Sequence[str],
    like,
) -> _Start:
    """The run's starting point: a fresh (or warm-started) learner state like `like`, written as a new run, or
    the latest checkpoint's (`resume`, as `_resumes` decided)."""
    primary = processes.is_primary()
    shardings = jax.tree.map(lambda leaf: leaf.sharding, like)
    if resume:
        state = learners.restore_state(run_dir, trainer, config, shardings=shardings)
        done_updates = int(state.updates)
        rundir.check_budget(config, done_updates)
        if primary:
            rundir.append_provenance(run_dir, "resume")
            if overrides:
                rundir.record_resume(run_dir, config, preset, overrides, done_updates)
            gap = rundir.missing_metrics(run_dir, rundir.truncate_metrics(run_dir, done_updates), done_updates)
            if gap:
                print(f"warning: {gap}", file=sys.stderr)
        wall_offset = max([row["wall_time"] for row in rundir.read_metrics(run_dir)], default=0.0)
        best_path = run_dir / "best.json"
        best = json.loads(best_path.read_text()) if best_path.exists() else None
        return _Start(state, done_updates, wall_offset, best)
    state = jax.jit(trainer.init, out_shardings=shardings)(jax.random.PRNGKey(config.seed), config.hparams())
    if config.init_from:
        state = jax.device_put(learners.warm_starter(config)(state), shardings)
    if primary:
        # Written once the start state exists: a warm start that fails leaves no half-made run directory.
        rundir.write_config(run_dir, config, preset)
        rundir.append_provenance(run_dir, "start")
    return _Start(state, 0, 0.0, None)


def _train_chunks(
    trainer: Trainer,
    config: RunConfig,
    run_dir: pathlib.Path,
    options: Options,
    start: _Start,
    runners: _ChunkRunners,
    evaluators: _Evaluators,
    compiling: Executor,
) -> tuple[Any, int, float]:
    """Runs chunks of updates (`runners`) from `start` until the budget, the time limit or a stop request,
    logging, evaluating (`evaluators.nominal`, compiled on `compiling` from the first chunk's end) and
    checkpointing between them; returns (learner state, updates done, wall seconds of training in all, earlier
    segments included)."""
    hparams = config.hparams()
    primary = processes.is_primary()
    eval_key = jax.random.PRNGKey(config.seed + FINAL_EVAL_SEED_OFFSET)
    checkpoints = run_dir / "checkpoints"
    state, done_updates, best = start.state, start.done_updates, start.best
    last_saved = done_updates
    clock = time.perf_counter()
    stop = StopRequests()
    steps_per_update = trainer.env_steps_per_update
    with contextlib.ExitStack() as stack:
        stack.enter_context(stop.installed())
        log = _RunLog(stack, run_dir, trainer, options, done_updates) if primary else None
        if log:
            log.bar.advance_to(done_updates * steps_per_update)
        while done_updates < trainer.num_updates:
            count = min(config.updates_per_chunk, trainer.num_updates - done_updates)
            runner = runners(count)
            chunk_start = time.perf_counter()
            state, metrics = runner(state, hparams)
            flat = rundir.flatten_metrics(jax.device_get(metrics))
            chunk_time = time.perf_counter() - chunk_start
            evaluators.compile_ahead(compiling, state, eval_key)
            bad = first_non_finite(flat)
            if bad is not None or not state_is_finite(state):
                raise TrainingDiverged(diverged_message(bad, done_updates, count, checkpoints))
            rows = list(
                metric_rows(
                    flat,
                    done_updates,
                    steps_per_update,
                    start.wall_offset + time.perf_counter() - clock,
                    count * steps_per_update / chunk_time,
                )
            )
            if crossed(config.eval_every_updates, done_updates, done_updates + count):
                result = evaluators.nominal(state, eval_key)
                rows[-1].update({f"eval/{name}": value for name, value in result.items() if isinstance(value, float)})
                if better(result, best):
                    best = {"updates": done_updates + count, **result}
                    save(run_dir / "best", done_updates + count, state, run_dir)
                    if primary:
                        rundir.write_json(run_dir / "best.json", best)
            done_updates += count
            if log:
                log.write(rows, done_updates * steps_per_update, flat)
            out_of_time = options.stop_after_s is not None and time.perf_counter() - clock > options.stop_after_s
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
                    rundir.record_checkpoint_config(run_dir)
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


class _RunLog:
    """The primary process's outputs between chunks: metrics.jsonl, the sinks (TensorBoard, wandb) and the
    progress bar, each closed with `stack`."""

    def __init__(
        self, stack: contextlib.ExitStack, run_dir: pathlib.Path, trainer: Trainer, options: Options, done_updates: int
    ):
        # TensorBoard hides the events a killed run logged past the checkpoint this one resumes from.
        resumed_at = done_updates * trainer.env_steps_per_update
        purge_step = resumed_at + 1 if done_updates else None
        self.sinks: list[Sink] = [TensorBoardSink(run_dir / "tensorboard", purge_step=purge_step)]
        if options.wandb:
            config = json.loads((run_dir / "config.json").read_text())
            run_id = wandb_run_id(run_dir.name, rundir.first_provenance(run_dir))
            self.sinks.append(WandbSink(options.wandb, run_dir, config, run_id))
        stack.enter_context(closing(self.sinks))
        self.bar = stack.enter_context(progress.Progress(trainer.num_updates * trainer.env_steps_per_update))
        self.file = stack.enter_context((run_dir / "metrics.jsonl").open("a"))

    def write(self, rows: list[dict], env_steps: int, flat: dict[str, np.ndarray]) -> None:
        for row in rows:
            self.file.write(json.dumps(row) + "\n")
            for sink in self.sinks:
                sink.write(row)
        self.file.flush()
        self.bar.update(env_steps, rows[-1]["steps_per_second"], flat)


def _final_evaluation(
    trainer: Trainer,
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    state,
    done_updates: int,
    train_time: float,
    evaluators: _Evaluators,
) -> dict:
    """Evaluates the final state (also under the randomised params, if any), writes eval.json and curve.png (the
    primary process) and returns the results."""
    eval_key = jax.random.PRNGKey(config.seed + FINAL_EVAL_SEED_OFFSET)
    result = evaluators.nominal(state, eval_key)
    if evaluators.randomized is not None:
        randomized = evaluators.randomized(state, eval_key)
        result.update({f"randomized/{name}": value for name, value in randomized.items() if name != "device"})
    result["train_wall_time"] = train_time
    result["env_steps"] = done_updates * trainer.env_steps_per_update
    result["finished"] = done_updates == trainer.num_updates
    if processes.is_primary():
        rundir.write_json(run_dir / "eval.json", result)
        plots.learning_curve(rundir.read_metrics(run_dir), run_dir / "curve.png", title=preset)
    return result


@contextlib.contextmanager
def closing(sinks: Sequence[Sink]) -> Iterator[None]:
    """Closes `sinks` after the `with` block. While an error propagates, a sink that fails to close (its last
    events cannot be written on a full disk) is reported in one line, so that it does not hide that error."""
    try:
        yield
    except BaseException:
        for sink in sinks:
            try:
                sink.close()
            except Exception as error:
                print(f"also: {type(sink).__name__} could not be closed ({error})", file=sys.stderr)
        raise
    for sink in sinks:
        sink.close()


def save(directory: pathlib.Path, step: int, state, run_dir: pathlib.Path) -> None:
    """`checkpoint.save`, with what to do next added to its error (free space, then resume)."""
    try:
        checkpoint.save(directory, step, state)
    except checkpoint.CheckpointError as error:
        raise rundir.resumable(
            checkpoint.CheckpointError(f"{error}; fix that, then resume the run to continue"), run_dir
        ) from error


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


def load_run(run_dir: pathlib.Path) -> tuple[RunConfig, Any]:
    """(config, latest learner state) of the run in `run_dir`, for notebooks and scripts."""
    config, _ = rundir.read_config(run_dir)
    return config, learners.restore_state(run_dir, learners.make_trainer(config, run_dir), config)
