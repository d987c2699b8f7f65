"""A run's compiled programs: its chunks of updates (the first compiled ahead, on a pool, while the start state is
made) and its evaluations (compiled on the pool while training runs). Nothing here decides when a program runs
or writes the run directory: the chunk loop (chunks.py) does.
"""

import dataclasses
from collections.abc import Callable
from concurrent.futures import Executor, Future

import jax
from jax.sharding import Mesh

from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.sharding import state_shardings
from jaxarm.agents.common.trainer import Trainer, make_chunk_runner
from jaxarm.runner import learners

FINAL_EVAL_SEED_OFFSET = 1_000_003
"""Evaluations during and at the end of training use key `seed + FINAL_EVAL_SEED_OFFSET`: the same episodes
each time, so evaluation rows compare checkpoints, not episode draws."""


def eval_key(config: RunConfig) -> jax.Array:
    """The key of every evaluation of a run (`FINAL_EVAL_SEED_OFFSET`)."""
    return jax.random.PRNGKey(config.seed + FINAL_EVAL_SEED_OFFSET)


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


class ChunkRunners:
    """The chunk programs (`make_chunk_runner`) by update count. The first chunk's program is traced and lowered
    before the start state is made, and compiled on a pool meanwhile: tracing and lowering hold the interpreter,
    compiling (or reading XLA's cache) lets it go. On one H200 a 2,048-env sorter run's first chunk ended
    0.3-3.1 s sooner (three pairs of runs). Other counts (a run's last, shorter chunk) compile at their first
    call."""

    def __init__(self, trainer: Trainer, shardings, ahead: dict[int, Future]):
        self._trainer, self._shardings, self._ahead = trainer, shardings, ahead
        self._programs: dict[int, Callable] = {}

    @classmethod
    def ahead(cls, trainer: Trainer, config: RunConfig, like, done_updates: int, pool: Executor) -> "ChunkRunners":
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
class Evaluators:
    """A run's evaluations, each one program: on the eval env (during training and at the end), and at the end
    under the config's randomised params where it has them."""

    nominal: learners.Evaluator
    randomized: learners.Evaluator | None

    @classmethod
    def of(cls, trainer: Trainer, config: RunConfig) -> "Evaluators":
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
