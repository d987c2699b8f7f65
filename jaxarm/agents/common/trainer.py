"""The protocol the runner drives, and the generic whole-run / chunked compilation built on it.

A learner provides a `Trainer`: `init(key, hparams)` and a single `update(state, hparams)`, both pure.
`run_updates` scans `update` any number of times; `make_train` turns that into the whole run as one
function `train(key, hparams)`, and the runner jits `run_updates` with a fixed count to compile in chunks.
"""

import dataclasses
from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxarm.envs import EnvState, Observation
from jaxarm.export.numpy_policy import NumpyPolicy


@dataclasses.dataclass(frozen=True)
class Trainer:
    """A learner, ready to run.

    Attributes:
      init: (key, hparams) -> learner state.
      init_for_acting: (key, hparams) -> `init`'s learner state without the envs' state or any replay (None):
        what acting, exporting and warm starts read, made without tracing an env reset; a checkpoint is restored
        into it to evaluate or export its policy.
      update: (learner state, hparams) -> (learner state, per-update metrics pytree of scalars).
      act: (learner state, observations [B, ...]) -> deterministic actions [B, A] (for evaluation).
      numpy_policy: learner state -> the same deterministic policy as numpy arrays (`NumpyPolicy`, which runs
        without JAX), or None for a learner that cannot export.
      num_updates: updates in the whole run.
      env_steps_per_update: env steps each update consumes.
      compiler_options: XLA options for the programs that run `update` (`jax.jit(..., compiler_options=...)`),
        chosen for the env by `jaxarm.envs.compiler_options`.
    """

    init: Callable[[jax.Array, Any], Any]
    init_for_acting: Callable[[jax.Array, Any], Any]
    update: Callable[[Any, Any], tuple[Any, Any]]
    act: Callable[[Any, Observation], jax.Array]
    num_updates: int
    env_steps_per_update: int
    compiler_options: dict[str, Any] = dataclasses.field(default_factory=dict)
    numpy_policy: Callable[[Any], NumpyPolicy] | None = None


def remaining_fraction(updates: jax.Array, num_updates: int) -> jax.Array:
    """[] float32: the share of a run of `num_updates` still to come after `updates` [] int, the factor of a step
    size annealed linearly to 0 over the run."""
    return 1.0 - updates.astype(jnp.float32) / num_updates


def run_updates(trainer: Trainer, state, hparams, num_updates: int):
    """Runs `num_updates` updates in one `lax.scan`; metrics come back stacked, [num_updates] per leaf."""
    return jax.lax.scan(lambda carry, _: trainer.update(carry, hparams), state, None, length=num_updates)


def make_train(trainer: Trainer) -> Callable[[jax.Array, Any], tuple[Any, Any]]:
    """The whole run as one pure function `train(key, hparams) -> (final state, metrics [num_updates])`."""

    def train(key, hparams):
        return run_updates(trainer, trainer.init(key, hparams), hparams, trainer.num_updates)

    return train


def make_chunk_runner(trainer: Trainer, updates_per_chunk: int, state_shardings=None):
    """A jitted `(state, hparams) -> (state, metrics [updates_per_chunk])`; compiled once, reused. The state
    comes out with `state_shardings` (a pytree of shardings like the state, see jaxarm.agents.common.sharding),
    or as XLA places it where None."""
    return jax.jit(
        partial(run_updates, trainer, num_updates=updates_per_chunk),
        donate_argnums=0,
        out_shardings=None if state_shardings is None else (state_shardings, None),
        compiler_options=trainer.compiler_options,
    )


@struct.dataclass
class EpisodeSummary:
    """The episodes of one update's window of env steps (`summarise_episodes`), each field [].

    Attributes:
      episodes: episodes that finished in the window.
      return_mean, length_mean, diverged_rate: over the episodes that finished (0 when none did).
      success_rate: training success, over the `judged` episodes (0 when none): successes that finished in the
        window / `judged`.
      judged: episodes that finished in the window, plus the envs that at its end are still in their first
        episode of the run without success, counted as failures so far.
    """

    episodes: jax.Array
    return_mean: jax.Array
    length_mean: jax.Array
    success_rate: jax.Array
    diverged_rate: jax.Array
    judged: jax.Array


def summarise_episodes(states: EnvState) -> EpisodeSummary:
    """Summarises a window of env steps, the states after each step, [T, B, ...] (time first; B may span several
    axes).

    Training success counts the envs still in their first episode: a failure runs to the time limit, so early in
    a run only episodes that succeeded quickly can have finished, and a rate over finished episodes alone starts
    near 1 before anything is learnt. Until an env's first episode ends (successes aside) it counts as a failure
    in every window; once every env has finished an episode (after one time limit at the latest) the rate is that
    of the episodes that finished. Envs whose episodes ran out together (most of them, while most fail) go on
    finishing in bursts one time limit apart, so this rate swings from window to window; summed over a span of
    one time limit or more, as curves do (`jaxarm.runner.plots.rolling_window`), it is the share of the episodes
    that succeeded.
    """
    done = states.done.astype(jnp.float32)
    count = done.sum()

    def mean(values, total=count):
        return (values.astype(jnp.float32) * done).sum() / jnp.maximum(total, 1.0)

    last = states.last_episode
    end = jax.tree.map(lambda leaf: leaf[-1], states)
    first_unsucceeded = (end.last_episode.length == 0) & ~end.episode.success
    judged = count + first_unsucceeded.sum()
    return EpisodeSummary(
        episodes=count,
        return_mean=mean(last.return_),
        length_mean=mean(last.length),
        success_rate=mean(last.success, total=judged),
        diverged_rate=mean(last.diverged),
        judged=judged,
    )
