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

This module holds a run's course: its directory and lock, where it starts (fresh or from a checkpoint) and its
final evaluation. The rest is one concern a module: the chunk loop (chunks.py), the compiled programs
(programs.py), what is written between chunks (runlog.py), stop requests (signals.py), how a run is driven
(options.py), the teacher stage (teacher.py), which only a run with a preset teacher enters, and the gate that
starts a try again (tries.py).
"""

import contextlib
import pathlib
import sys
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import jax

from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.sharding import data_mesh, envs_split_over
from jaxarm.agents.common.trainer import Trainer
from jaxarm.runner import learners, metrics_log, plots, processes, progress, provenance, resumes, rundir, teacher, tries
from jaxarm.runner.chunks import Start, TrainingDiverged, TrainingInterrupted, read_best, train_chunks
from jaxarm.runner.options import Options
from jaxarm.runner.programs import ChunkRunners, Evaluators, eval_key, state_like

__all__ = ["Options", "TrainingDiverged", "TrainingInterrupted", "load_run", "resume", "train"]


def train(
    config: RunConfig, run_dir: pathlib.Path, *, preset: str = "custom", resume: bool = False, options=Options()
) -> dict:
    """Trains `config` into `run_dir` and returns the final evaluation (also written to eval.json).

    With `resume`, continues from the directory's latest checkpoint (a directory with none starts afresh).
    Without, the directory must be new, empty, or hold a run that never reached its first checkpoint. Raises
    rundir.RunDirError (foreign files, in use, already a run), TrainingDiverged on NaN/inf, TrainingInterrupted
    after Ctrl-C or SIGTERM; with `options.stop_after_s`, the first chunk that ends past it, counted from this call
    (or from `options.clock_start`), is checkpointed and the evaluation describes that state. With several processes
    (`jax.distributed`) every process calls this with the same arguments; process 0 alone writes the directory
    (processes.py). A run to warm-start from and a teacher named by preset (`init_from=preset:NAME`,
    `teacher=preset:NAME`, found through `options.presets`) are trained first, into `run_dir/warm_start` and
    `run_dir/teacher` (teacher.py); a time limit counts every stage, and every compilation.
    """
    options = options.clock_started()  # the time limit counts from here, every stage and compilation included
    run_dir = pathlib.Path(run_dir)
    rundir.check_holds_a_run_or_nothing(run_dir)
    with _locked_by_primary(run_dir):
        return _train_locked(config, preset, run_dir, resume, options)


def resume(run_dir: pathlib.Path, overrides: Sequence[str] = (), options=Options()) -> tuple[dict, RunConfig]:
    """Continues the run in `run_dir` from its latest checkpoint with the `key=value` overrides a resumed run may
    take (resumes.RESUMABLE_KEYS; recorded in config.json and resumes.jsonl). Returns (evaluation, config). A run
    that has finished, resumed without overrides, is left as it is: its eval.json is returned."""
    options = options.clock_started()  # as in `train`
    run_dir = pathlib.Path(run_dir)
    # Checked before the lock writes anything: a directory that is no run, or overrides it may not take.
    config, preset = rundir.read_config(run_dir)
    unchecked = resumes.check_config_unedited(run_dir, config)
    config = resumes.apply_resume_overrides(config, list(overrides))
    with _locked_by_primary(run_dir):
        if unchecked and processes.is_primary():
            print(f"warning: {unchecked}", file=sys.stderr)
        finished = None if overrides else rundir.finished_evaluation(run_dir, config)
        if finished is not None:
            # Nothing asked: evaluating again would only rewrite eval.json (experiments.eval writes its own file).
            # A row a killed process half wrote past the end is still dropped, as every resume drops it.
            if processes.is_primary():
                metrics_log.truncate_metrics(run_dir, config.num_updates)
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


def _train_locked(
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    resuming: bool,
    options: Options,
    overrides: Sequence[str] = (),
) -> dict:
    """`train`, with the lock held: the run's learner (`_train_learner`), after its stages: the run it warm-starts
    from and its teacher, where the config names them by preset (a stage's evaluation is returned where a time
    limit stopped it). Where each try trains its warm start again (`retry_warm_start`), a try that failed its gate
    comes back here, set aside with its warm start, and the stages and the learner run again."""
    while True:
        for stage, stage_config in teacher.stages(config, run_dir, options):
            stopped = teacher.train_stage(
                stage, stage_config, config, preset, run_dir, resuming, options, train=train, resume=resume
            )
            if stopped is not None:
                return stopped
        try:
            return _train_learner(config, preset, run_dir, resuming, options, overrides)
        except tries.TryFailed:
            overrides = ()


def _train_learner(
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    resume: bool,
    options: Options,
    overrides: Sequence[str],
) -> dict:
    """Trains `config`'s own learner into `run_dir`, the lock held; a resume's `overrides` are recorded once its
    checkpoint is restored. After a try set aside with its warm start (`retry_warm_start`) this starts the next
    (`_resumes` finds the run between tries); such a try raises TryFailed out of here once set aside."""
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
    evaluators = Evaluators.of(trainer, config)
    mesh = data_mesh(options.devices)
    if processes.is_primary():
        progress.explain_gspmd(mesh.devices.size)
    # Under the mesh, VmapEnv steps each device's envs on that device (jaxarm.envs.wrappers.over_env_batch). The
    # pool compiles the first chunk while the start state is made, then the evaluations while it runs; leaving
    # it waits for that.
    with envs_split_over(mesh), ThreadPoolExecutor(1, thread_name_prefix="compile") as compiling:
        resume = _resumes(run_dir, resume)
        like = state_like(trainer, config, mesh)
        resumed_at = (checkpoint.latest_step(run_dir / "checkpoints") or 0) if resume else 0
        runners = ChunkRunners.ahead(trainer, config, like, resumed_at, compiling)
        # Behind the first chunk's program on the pool: compiled while the first chunk runs, ready at its end.
        evaluators.compile_ahead(compiling, like, eval_key(config))
        start = _start(trainer, config, preset, run_dir, resume, overrides, like)
        while True:
            try:
                state, done_updates, train_time = train_chunks(
                    trainer, config, run_dir, options, start, runners, evaluators
                )
                break
            except tries.TryFailed as failed:
                _set_aside(config, run_dir, failed)
                if config.retry_warm_start:
                    raise
                start = _start(trainer, config, preset, run_dir, False, (), like)
        return _final_evaluation(
            trainer, config, preset, run_dir, state, done_updates, train_time, start.try_index + 1, evaluators
        )


def _set_aside(config: RunConfig, run_dir: pathlib.Path, failed: tries.TryFailed) -> None:
    """Sets the failed try's files aside (the primary process, the others waiting for it) and says so."""
    if processes.is_primary():
        done = tries.tries_set_aside(run_dir) + 1
        stages = (rundir.WARM_START_DIR,) if config.retry_warm_start else ()
        folder = tries.set_aside_try(run_dir, stages)
        again = ", its warm start trained again first" if stages else ""
        print(
            f"try {done} of {config.tries} failed its gate ({failed}): set aside in {folder}; starting try "
            f"{done + 1}{again}",
            file=sys.stderr,
        )
    processes.wait_for_all("try set aside")


def _resumes(run_dir: pathlib.Path, resume: bool) -> bool:
    """Whether the run in `run_dir` resumes from its latest checkpoint (`resume`), after checking that there is
    one to resume, or none where the run starts; a run that died before its first checkpoint starts afresh, and a
    try after others set aside that did starts that try afresh."""
    primary = processes.is_primary()
    has_run = (run_dir / "config.json").exists()
    restart = has_run and not rundir.any_checkpoint_files(run_dir)
    # Every process has looked before the primary clears anything.
    processes.wait_for_all("run directory read")
    if restart and tries.tries_set_aside(run_dir):
        # Between tries: the run's config, provenance and resumes, and its tries set aside, stay.
        if primary:
            rundir.clear_run(run_dir, tries.TRY_FILES)
        resume = False
    elif restart:
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
) -> Start:
    """The run's starting point: a fresh (or warm-started) learner state like `like`, written as a new run, or
    the latest checkpoint's (`resume`, as `_resumes` decided), in the try the run directory holds (`tries_set_aside`):
    each try draws its own randomness, the first the seed's own, and its clock goes on from the tries before."""
    primary = processes.is_primary()
    shardings = jax.tree.map(lambda leaf: leaf.sharding, like)
    index = tries.tries_set_aside(run_dir)
    if resume:
        state = learners.restore_state(run_dir, trainer, config, shardings=shardings)
        done_updates = int(state.updates)
        resumes.check_budget(config, done_updates)
        best = read_best(run_dir)  # checked before this resume writes anything
        if primary:
            provenance.append_provenance(run_dir, "resume")
            if overrides:
                resumes.record_resume(run_dir, config, preset, overrides, done_updates)
            gap = metrics_log.missing_metrics(
                run_dir, metrics_log.truncate_metrics(run_dir, done_updates), done_updates
            )
            if gap:
                print(f"warning: {gap}", file=sys.stderr)
        wall_offset = max([row["wall_time"] for row in metrics_log.read_metrics(run_dir)], default=0.0)
        return Start(state, done_updates, wall_offset, best, index)
    key = jax.random.PRNGKey(config.seed)
    key = jax.random.fold_in(key, index) if index else key
    state = jax.jit(trainer.init, out_shardings=shardings)(key, config.hparams())
    if config.init_from:
        source = teacher.warm_start_run(config, run_dir)
        state = jax.device_put(learners.warm_starter(config, source)(state), shardings)
    if primary:
        # Written once the start state exists: a warm start that fails leaves no half-made run directory.
        rundir.write_config(run_dir, config, preset)
        provenance.append_provenance(run_dir, f"try {index + 1}" if index else "start")
    # The failed tries' time counts: a retried run's train wall time is all it took.
    return Start(state, 0, _tries_wall_time(run_dir), None, index)


def _tries_wall_time(run_dir: pathlib.Path) -> float:
    """The train wall time of the tries of the run in `run_dir` set aside so far (0 where none was): the latest clock
    in their metrics, each try's clock going on from the tries before it, in the command that set it aside or in a
    later one."""
    folders = (run_dir / tries.TRIES_DIR / str(index) for index in range(tries.tries_set_aside(run_dir)))
    return max((row["wall_time"] for folder in folders for row in metrics_log.read_metrics(folder)), default=0.0)


def _final_evaluation(
    trainer: Trainer,
    config: RunConfig,
    preset: str,
    run_dir: pathlib.Path,
    state,
    done_updates: int,
    train_time: float,
    tries_taken: int,
    evaluators: Evaluators,
) -> dict:
    """Evaluates the final state (also under the randomised params, if any), writes eval.json (with the `tries_taken`
    of a gated run) and curve.png (the primary process) and returns the results."""
    key = eval_key(config)
    result = evaluators.nominal(state, key)
    if evaluators.randomized is not None:
        randomized = evaluators.randomized(state, key)
        result.update({f"randomized/{name}": value for name, value in randomized.items() if name != "device"})
    result["train_wall_time"] = train_time
    result["env_steps"] = done_updates * trainer.env_steps_per_update
    result["finished"] = done_updates == trainer.num_updates
    result["tries"] = tries_taken
    if processes.is_primary():
        rundir.write_json(run_dir / "eval.json", result)
        rows = metrics_log.read_metrics(run_dir)
        plots.learning_curve(rows, run_dir / "curve.png", preset, window_at_least=config.updates_per_time_limit())
    return result


def load_run(run_dir: pathlib.Path) -> tuple[RunConfig, Any]:
    """(config, latest learner state) of the run in `run_dir`, for notebooks and scripts."""
    config, _ = rundir.read_config(run_dir)
    return config, learners.restore_state(run_dir, learners.make_trainer(config, run_dir), config)
