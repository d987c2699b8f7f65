"""The environment contract every jaxarm env follows.

`reset(key, params) -> EnvState` and `step(state, action, params) -> EnvState` are pure functions of their
arguments: jit-, vmap- and grad-safe, no Python side effects. Params are data (vmap over params is domain
randomisation); static shapes and counts are constructor arguments.

Subclasses implement the task in `_reset` and `_transition`; this module owns the bookkeeping that must
be the same everywhere: action clipping, NaN-action handling, the time limit, and episode statistics.

Non-finite actions: inside jit there is no way to raise, so a NaN component is replaced by 0 (the env steps
with a zero command there), an infinite one is clipped to its bound like any other, and either is counted in
`state.episode.nan_actions`. Code that runs outside jit (adapters, evaluation) calls `check_action` for a
clear error instead.

Diverged physics: a step whose observation or reward is not finite, or whose observation exceeds
`DIVERGENCE_LIMIT` in magnitude (a simulator blowing up), ends the episode as terminated with reward 0 and
a zero observation, and is flagged in `state.episode.diverged`, so one unstable env among thousands cannot
poison a learner's batch. A reset observation is cleaned the same way: zeroed, and its episode flagged in
`state.episode.diverged`.

Camera images: an env that `draws_images` leaves obs[IMAGE] zero in `_reset` and `_transition` and draws it
in `images`, from the sim alone, which `reset` and `step` call (after the cleaning above: an image, uint8,
cannot diverge). `AutoReset` can then draw a new episode's first
images only for the envs of a batch that start one, instead of drawing a start for every env at every step.

Stepping a plain (not auto-reset) env past the end of its episode changes nothing the episode reported:
`last_episode` keeps the statistics of the step that ended it.

Checks that need the host: a fault the env can only report from outside the compiled program (MJX Warp's
dropped contacts) raises there, at every step by default. Learners trace their rollouts inside
`deferred_step_checks()`, where a step only records such faults in its sim, `AutoReset` carries them into the
next episode (`carried_over`), and one call of `checked` after the rollout raises on any of them: one trip to
the host per rollout instead of one per step.

Params out of their declared ranges (made with `params.replace(...)`, which checks nothing) are refused with a
ValueError by a `reset` called outside jit, and by the adapters that step an env from outside (jaxarm.interop);
inside a compiled program there is no way to raise.
"""

import abc
import contextlib
import contextvars
import dataclasses
from collections.abc import Iterator, Mapping
from typing import Any, Generic, Protocol, TypeVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxarm import ranges
from jaxarm.envs.observation import IMAGE, with_image

DIVERGENCE_LIMIT = 1e6
"""Observations beyond this magnitude count as a diverged simulation (see the module docstring)."""
_STEP_CHECKS_DEFERRED: contextvars.ContextVar[bool] = contextvars.ContextVar("deferred_step_checks", default=False)


@contextlib.contextmanager
def deferred_step_checks() -> Iterator[None]:
    """While active, env steps traced in this thread record the faults that need the host to raise on (see the
    module docstring) instead of checking them; whoever traces them calls `Env.checked` on the states they lead
    to, in the same traced function. Only tracing reads it: a jitted function first called inside it keeps its
    deferred steps when called again outside."""
    token = _STEP_CHECKS_DEFERRED.set(True)
    try:
        yield
    finally:
        _STEP_CHECKS_DEFERRED.reset(token)


def step_checks_deferred() -> bool:
    """Steps traced now leave their host checks to `Env.checked` (`deferred_step_checks`)."""
    return _STEP_CHECKS_DEFERRED.get()


class HasEpisodeLimit(Protocol):
    """What the base class reads from every env's params: the time limit, in env steps."""

    max_episode_steps: jax.Array


Params = TypeVar("Params", bound=HasEpisodeLimit)
Sim = TypeVar("Sim")


Observation = Any
"""What an env observes: a float32 array, or a dict of named arrays (e.g. {"image": uint8 [H, W, C],
"proprio": float32 [P]}) whose shapes and dtypes `EnvSpec.observation_parts` declares."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class EnvSpec:
    """Static description of an env's spaces.

    An observation is either one flat float32 array (`observation_shape`) or a dict of named arrays with their
    own shapes and dtypes (`observation_parts`, e.g. a camera image as uint8); exactly one of the two is given.

    Attributes:
      observation_shape: shape of one flat float32 observation, e.g. (9,); None when `observation_parts` is set.
      action_shape: shape of one action, e.g. (2,).
      action_low: lower bound of each action component; actions are clipped to it.
      action_high: upper bound of each action component.
      observation_parts: name -> shape and dtype of each part of a dict observation; None for a flat one.
    """

    observation_shape: tuple[int, ...] | None = None
    action_shape: tuple[int, ...]
    action_low: float = -1.0
    action_high: float = 1.0
    observation_parts: Mapping[str, jax.ShapeDtypeStruct] | None = None

    def __post_init__(self) -> None:
        if (self.observation_shape is None) == (self.observation_parts is None):
            raise ValueError("EnvSpec needs exactly one of observation_shape (flat) and observation_parts (a dict)")

    @property
    def observation(self) -> Any:
        """The observation's structure: a `jax.ShapeDtypeStruct`, or a dict of them (`observation_parts`)."""
        if self.observation_parts is not None:
            return dict(self.observation_parts)
        return jax.ShapeDtypeStruct(self.observation_shape, jnp.float32)

    @property
    def flat_observation(self) -> bool:
        """The observation is one float32 array (not a dict of parts)."""
        return self.observation_parts is None

    @property
    def observation_size(self) -> int:
        """Values in one flat observation; ValueError for a dict observation, which has no single size."""
        if self.observation_shape is None:
            raise ValueError(f"a dict observation ({', '.join(self.observation_parts or {})}) has no single size")
        return int(np.prod(self.observation_shape))

    @property
    def action_size(self) -> int:
        return int(np.prod(self.action_shape))

    def zero_observation(self, batch_shape: tuple[int, ...] = ()) -> Observation:
        """An all-zero observation with leading `batch_shape`, every part in its own dtype."""
        return jax.tree.map(lambda part: jnp.zeros(batch_shape + part.shape, part.dtype), self.observation)


@struct.dataclass
class EpisodeStats:
    """Statistics of one episode, scalars per env.

    Attributes:
      return_: sum of rewards so far.
      length: env steps so far.
      success: whether the task's success condition held at any step.
      nan_actions: steps whose action had a NaN or infinite component (NaN replaced by zero, inf clipped).
      diverged: the simulation diverged and ended the episode.
    """

    return_: jax.Array
    length: jax.Array
    success: jax.Array
    nan_actions: jax.Array
    diverged: jax.Array

    @classmethod
    def zeros(cls) -> "EpisodeStats":
        return cls(
            return_=jnp.zeros((), jnp.float32),
            length=jnp.zeros((), jnp.int32),
            success=jnp.zeros((), jnp.bool_),
            nan_actions=jnp.zeros((), jnp.int32),
            diverged=jnp.zeros((), jnp.bool_),
        )


class EnvState(struct.PyTreeNode, Generic[Sim]):
    """Everything an env carries between steps. Shapes are per env; vmapped envs add a leading [B].

    Attributes:
      sim: the env's own physics/task state (a typed pytree, defined by the env).
      obs: observation after this step (after an auto-reset: the new episode's first); an array
        [*observation_shape] or a dict of parts (`EnvSpec.observation_parts`).
      reward: [] reward of the last step.
      terminated: [] bool, the task ended (no bootstrapping from `final_obs`).
      truncated: [] bool, the time limit ended the episode (bootstrap from `final_obs`).
      final_obs: observation reached by the last step, before any auto-reset (same structure as `obs`).
      step_count: [] int32, steps taken in the current episode.
      episode: running statistics of the current episode.
      last_episode: statistics of the most recently finished episode (valid where `done`).
      info: per-step diagnostics of the env (a typed pytree, defined by the env).
      key: PRNG key the env consumes for auto-resets.
    """

    sim: Sim
    obs: Observation
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    final_obs: Observation
    step_count: jax.Array
    episode: EpisodeStats
    last_episode: EpisodeStats
    info: Any
    key: jax.Array

    @property
    def done(self) -> jax.Array:
        """[] bool, the last step ended the episode (terminated or truncated)."""
        return self.terminated | self.truncated


@struct.dataclass
class Transition(Generic[Sim]):
    """What an env's task logic returns for one step; the base class does the rest."""

    sim: Sim
    obs: Observation
    reward: jax.Array
    terminated: jax.Array
    success: jax.Array
    info: Any


def observation_healthy(obs: Observation) -> jax.Array:
    """[] bool: every float part of `obs` is finite and below `DIVERGENCE_LIMIT` in magnitude (False for NaN);
    integer parts (camera images) cannot diverge."""
    healthy = jnp.ones((), jnp.bool_)
    for part in jax.tree.leaves(obs):
        if jnp.issubdtype(part.dtype, jnp.floating):
            healthy &= jnp.all(jnp.abs(part) < DIVERGENCE_LIMIT)
    return healthy


def zeroed_unless(healthy: jax.Array, obs: Observation) -> Observation:
    """`obs` where `healthy`, else all zeros (every part in its own dtype)."""
    return jax.tree.map(lambda part: jnp.where(healthy, part, jnp.zeros_like(part)), obs)


def check_concrete_params(params) -> None:
    """ValueError naming the first env param out of its declared range, for params known outside jit; nothing
    for params being traced (inside jit or vmap), whose values are not known yet."""
    if not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(params)):
        ranges.check_params(params)


def check_action(action: np.ndarray, spec: EnvSpec) -> np.ndarray:
    """Outside-jit validation: raises ValueError on a wrong shape or a NaN; returns a float32 array."""
    array = np.asarray(action, dtype=np.float32)
    if array.shape != spec.action_shape:
        raise ValueError(f"action has shape {array.shape}, expected {spec.action_shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"action contains NaN or inf: {array}")
    return array


class Env(abc.ABC, Generic[Params, Sim]):
    """Base class of jaxarm envs. Params must have an int field `max_episode_steps`.

    Attributes:
      spec: observation and action shapes and bounds.
      cpu_max_envs: the largest batch known to step safely on a CPU, or None for no known limit; `VmapEnv`
        warns above it there.
      uses_mjx: the env steps MJX physics; learners then compile their programs with jaxarm's process-wide
        XLA:CPU setting for MJX rather than for everything else (`jaxarm.envs.compiler_options`).
      draws_with_gl: `render` draws with MuJoCo's OpenGL renderer, which needs a GL platform (`MUJOCO_GL`).
    """

    spec: EnvSpec
    cpu_max_envs: int | None = None
    uses_mjx: bool = False
    draws_with_gl: bool = False

    @abc.abstractmethod
    def default_params(self) -> Params:
        """The env's default params (a pytree of arrays)."""

    @abc.abstractmethod
    def _reset(self, key: jax.Array, params: Params) -> tuple[Sim, Observation, Any]:
        """Samples a fresh episode: returns (sim, first observation, info)."""

    @abc.abstractmethod
    def _transition(self, sim: Sim, action: jax.Array, params: Params) -> Transition[Sim]:
        """Advances the task by one step with an already clipped, finite action."""

    def observation_source_index(self, source: "Env") -> np.ndarray:
        """[observation_size] int: per input of this env's observation, the index of the same quantity in
        `source`'s observation, or −1 where `source` has none (a learner trained on `source` can then be
        warm-started here). Here: the identity, for observations of the same shape; ValueError otherwise."""
        if source.spec.observation_shape != self.spec.observation_shape:
            raise ValueError(
                f"{type(self).__name__}'s observation {self.spec.observation_shape} has no mapping "
                f"from {type(source).__name__}'s {source.spec.observation_shape}"
            )
        return np.arange(self.spec.observation_size)

    def observation_source_shift(self, source: "Env") -> np.ndarray:
        """[observation_size] float32: per input, how much more it reads than its source input
        (`observation_source_index`) where both envs stand in the same situation, as a vector to a target that
        stands elsewhere in this env's scene does; 0 where it has no source. A warm start moves the source's
        observation statistics by it, so that the trained networks read the same standardised inputs. Here: 0."""
        return np.zeros(self.spec.observation_size, np.float32)

    def render(self, state: EnvState[Sim], params: Params) -> np.ndarray:
        """One (non-batched) state as an RGB frame, uint8 [H, W, 3], drawn without a window."""
        raise NotImplementedError(f"{type(self).__name__} has no renderer")

    @property
    def draws_images(self) -> bool:
        """The camera part of the observation, obs[IMAGE], is drawn by `images` (see the module docstring)."""
        return False

    def images(self, sim: Sim, params: Params) -> jax.Array:
        """uint8 [H, W, C]: what the env's cameras see in `sim`; only for an env that `draws_images`."""
        raise NotImplementedError(f"{type(self).__name__} draws no images")

    def blank_image(self) -> jax.Array:
        """uint8 zeros shaped as obs[IMAGE]: the image `_reset` and `_transition` leave for `images` to draw."""
        return jnp.zeros(self.spec.observation[IMAGE].shape, jnp.uint8)

    def carried_over(self, ended: Sim, fresh: Sim) -> Sim:
        """The sim `AutoReset` starts a new episode with: `fresh` (from `reset`) with what must outlive the
        `ended` episode's sim, such as faults not yet checked (`checked`). Here: `fresh`."""
        return fresh

    def checked(self, state: EnvState[Sim]) -> EnvState[Sim]:
        """`state` (any leading batch axes) as it is, behind a check that raises a RuntimeError when the compiled
        program runs if a step that led to it since the first reset recorded a fault under
        `deferred_step_checks`. Here: no check, as this env records none."""
        return state

    def reset(self, key: jax.Array, params: Params) -> EnvState[Sim]:
        """Starts an episode. `key` is a PRNG key; the returned state holds a descendant for auto-resets.
        Called outside jit, it first checks `params` against their declared ranges (ValueError)."""
        check_concrete_params(params)
        state = self.reset_without_images(key, params)
        if not self.draws_images:
            return state
        obs = with_image(state.obs, self.images(state.sim, params))
        return state.replace(obs=obs, final_obs=obs)

    def reset_without_images(self, key: jax.Array, params: Params) -> EnvState[Sim]:
        """`reset`, with obs[IMAGE] left zero where the env `draws_images`."""
        reset_key, carry_key = jax.random.split(key)
        sim, raw_obs, info = self._reset(reset_key, params)
        healthy = observation_healthy(raw_obs)
        obs = zeroed_unless(healthy, raw_obs)
        return EnvState(
            sim=sim,
            obs=obs,
            reward=jnp.zeros((), jnp.float32),
            terminated=jnp.zeros((), jnp.bool_),
            truncated=jnp.zeros((), jnp.bool_),
            final_obs=obs,
            step_count=jnp.zeros((), jnp.int32),
            episode=dataclasses.replace(EpisodeStats.zeros(), diverged=~healthy),
            last_episode=EpisodeStats.zeros(),
            info=info,
            key=carry_key,
        )

    def step(self, state: EnvState[Sim], action: jax.Array, params: Params) -> EnvState[Sim]:
        """Advances one step: clips the action, zeroes NaNs, applies the time limit, updates statistics."""
        action = jnp.asarray(action, jnp.float32).reshape(self.spec.action_shape)
        non_finite = jnp.any(~jnp.isfinite(action))
        action = jnp.clip(jnp.nan_to_num(action, nan=0.0), self.spec.action_low, self.spec.action_high)
        out = self._transition(state.sim, action, params)
        healthy = observation_healthy(out.obs) & jnp.isfinite(out.reward)
        obs = zeroed_unless(healthy, out.obs)
        if self.draws_images:
            obs = with_image(obs, self.images(out.sim, params))
        reward = jnp.where(healthy, out.reward, 0.0).astype(jnp.float32)
        terminated = out.terminated | ~healthy
        step_count = state.step_count + 1
        truncated = (step_count >= params.max_episode_steps) & ~terminated
        episode = EpisodeStats(
            return_=state.episode.return_ + reward,
            length=state.episode.length + 1,
            success=state.episode.success | (out.success & healthy),
            nan_actions=state.episode.nan_actions + non_finite.astype(jnp.int32),
            diverged=state.episode.diverged | ~healthy,
        )
        done = terminated | truncated
        # A state that is done but not reset (step_count > 0: AutoReset starts the next episode at 0) is a plain
        # env stepped past its end; the episode it reported stays reported.
        ends_episode = done & ~(state.done & (state.step_count > 0))
        last_episode = jax.tree.map(lambda new, old: jnp.where(ends_episode, new, old), episode, state.last_episode)
        return state.replace(
            sim=out.sim,
            obs=obs,
            reward=reward,
            terminated=terminated,
            truncated=truncated,
            final_obs=obs,
            step_count=step_count,
            episode=episode,
            last_episode=last_episode,
            info=out.info,
        )
