"""A run's learner built from its config and run directory: its trainer (with a teacher's policy loaded where it
has one), its state restored from a checkpoint or warm-started from another run, and its evaluator.

The run directory's files (its config, metrics, lock, records) are rundir.py's and its neighbours'
(metrics_log.py, provenance.py, resumes.py); this module reads a run and writes nothing into it.
"""

import concurrent.futures
import contextvars
import functools
import pathlib
from collections.abc import Callable
from typing import Any

import jax
from jax.sharding import NamedSharding, PartitionSpec

from jaxarm.agents import registry
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.agents.common.sharding import data_mesh, envs_split_over
from jaxarm.agents.common.teachers import learner_as_teacher
from jaxarm.runner.rundir import read_config
from jaxarm.runner.teacher import check_teacher_fits, teacher_run


def make_trainer(config: RunConfig, run_dir: pathlib.Path | None = None):
    """The trainer of `config`'s learner, with its teacher's policy loaded where it has one (distillation,
    `jaxarm.agents.common.teachers`): from the run `config.teacher` names, or, named by preset, from
    `run_dir/teacher`."""
    teacher = teacher_run(config, run_dir)
    if teacher is None:
        return registry.make_trainer(config)
    return registry.make_trainer(config, teacher=load_teacher(teacher, config))


def load_teacher(run_dir: pathlib.Path, student: RunConfig | None = None):
    """The policy of the run in `run_dir` (its latest checkpoint) as a teacher (`learner_as_teacher`); RunDirError
    or CheckpointError for a run that cannot be read, and with `student` (the config of the run it teaches)
    ValueError where the two envs do not fit (`check_teacher_fits`)."""
    config, _ = read_config(run_dir)
    if student is not None:
        check_teacher_fits(student, config, registry.teacher_of(student))
    trainer = make_trainer(config, run_dir)
    state = restore_state(run_dir, trainer, config, acting=True)
    return learner_as_teacher(trainer, state)


def restore_state(
    run_dir: pathlib.Path, trainer, config: RunConfig, best: bool = False, shardings=None, acting: bool = False
):
    """The latest checkpointed learner state of `run_dir`, or with `best` the one that scored best in evaluation
    during training (CheckpointError if none or mismatched), placed with `shardings` (a pytree like the state;
    None: on this process's first device); leaves added to the learner since it was saved start fresh.

    With `acting`, the state for acting (`Trainer.init_for_acting`: no envs, no replay), which is all that
    evaluating, exporting or teaching reads: its shapes come without tracing an env reset (1.7 s of the sorter's
    on 2 CPU cores) and the envs' part of the checkpoint is not read (most of it: a sorter's 8,192 envs)."""
    key, hparams = jax.random.PRNGKey(config.seed), config.hparams()
    init = trainer.init_for_acting if acting else trainer.init
    like = jax.eval_shape(init, key, hparams)
    fresh = functools.partial(jax.jit(init, out_shardings=shardings), key, hparams)
    directory = run_dir / ("best" if best else "checkpoints")
    return checkpoint.restore(directory, like, shardings=shardings, fresh=fresh, partial=acting)


def warm_starter(config: RunConfig, source_dir: pathlib.Path) -> Callable[[Any], Any]:
    """fresh learner state -> the same warm-started from the latest checkpoint of the run in `source_dir` (the one
    `config.init_from` names), by the learner's own warm start (`jaxarm.agents.registry.Learner.warm_start`).
    ValueError or CheckpointError when that run cannot serve."""
    source, _ = read_config(source_dir)
    learner = registry.learner_for(config)
    warm_start = learner.warm_start
    if warm_start is None or registry.learner_for(source) is not learner:
        with_warm_starts = [name for name, each in registry.LEARNERS.items() if each.warm_start is not None]
        raise ValueError(
            f"init_from: warm starts exist for {', '.join(with_warm_starts)} only, from a run of the same learner "
            f"({source_dir} is {registry.name_of(source)}, this run {registry.name_of(config)})"
        )
    trained = restore_state(source_dir, make_trainer(source, source_dir), source, acting=True)
    env, source_env = config.make_env()[0], source.make_env()[0]
    index, shift = env.observation_source_index(source_env), env.observation_source_shift(source_env)
    return lambda state: warm_start(config, source, state, trained, index, shift)


class Evaluator:
    """(learner state, key) -> deterministic-policy results on fresh episodes of an eval env, as a JSON-ready dict.

    Its program is compiled once: ahead, on a thread (`compile_ahead`), or else at the first call."""

    def __init__(self, program: Any):
        self._program = program  # jitted: (learner state, key) -> evaluate's results
        self._compiled: concurrent.futures.Future | None = None

    def compile_ahead(self, pool: concurrent.futures.Executor, state, key: jax.Array) -> None:
        """Starts compiling the program on `pool` for states like `state` (same shapes and shardings) and keys
        like `key`, unless started before. A training loop calls this before its first chunk, with its state's
        shapes, so that its evaluations need not wait for tracing, lowering and compiling (measured when called
        at the first chunk's end: a 4-GPU sorter run's final evaluation took 2.3 s instead of 7 s; the chunk it
        overlapped 2-3 s longer on MJX Warp, H200s). The program is traced in this thread's context
        (`jaxarm.agents.common.sharding.envs_split_over` among it)."""
        if self._compiled is not None:
            return
        # Shapes alone: the training loop may donate `state` to its next chunk before the thread reads it. The
        # key as a fresh one is (on no device yet), so that it can join a program spread over several processes.
        like_state = jax.tree.map(
            lambda leaf: jax.ShapeDtypeStruct(leaf.shape, leaf.dtype, sharding=leaf.sharding), state
        )
        like_key = jax.ShapeDtypeStruct(key.shape, key.dtype)
        lower = functools.partial(self._program.lower, like_state, like_key)
        self._compiled = pool.submit(contextvars.copy_context().run, lambda: lower().compile())

    def __call__(self, state, key: jax.Array) -> dict:
        program = self._program if self._compiled is None else self._compiled.result()
        return {**program(state, key).summary(), "device": jax.devices()[0].device_kind}


def make_evaluator(trainer, config: RunConfig, episodes: int, randomized: bool = False) -> Evaluator:
    """The evaluator of `trainer`'s deterministic policy on `episodes` fresh episodes of `config`'s eval env, with
    the config's `randomize` params drawn per episode if `randomized`."""
    env, env_params = config.make_eval_env(randomized)

    def evaluate_policy(learner, key: jax.Array):
        return evaluate(env, env_params, lambda obs: trainer.act(learner, obs), key, episodes)

    return Evaluator(jax.jit(evaluate_policy))


def evaluate_state(trainer, config: RunConfig, state, episodes: int, seed: int) -> dict:
    """Deterministic-policy results on `episodes` fresh episodes, as a JSON-ready dict.

    `state` is placed and the program traced as training places and traces its evaluations (replicated over
    `data_mesh()`, the episodes split over it), so that with training's `eval_episodes` this is the program the
    run compiled, read back from the compilation cache (jaxarm/runner/cache.py). A state on one device instead
    lowers to another program, its arguments unannotated and its functions numbered otherwise, whose cache key
    differs: the first `experiments.eval` after a CPU training compiled again (365.7 s for td3_peg)."""
    mesh = data_mesh()
    with envs_split_over(mesh):
        placed = jax.device_put(state, NamedSharding(mesh, PartitionSpec()))
        return make_evaluator(trainer, config, episodes)(placed, jax.random.PRNGKey(seed))
