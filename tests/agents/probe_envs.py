"""Tiny envs with known optimal actions and values, for testing any learner (PPO, TD3, ...).

Each isolates one thing a learner can get wrong:
- `TargetActionEnv`: one step, reward −Σ(a − obs)²; the optimal action is the observation itself and the
  optimal value is 0. Tests that the policy learns an observation-dependent continuous action. With
  `obs_offset` and `obs_scale` the env shows offset + scale · target instead (badly scaled inputs, for
  observation normalisers).
- `ImageTargetEnv`: `TargetActionEnv` seen through a camera: one step, the target is −0.5 or +0.5 and shows only
  as a dark or bright uint8 image; the optimal action is the target. Tests that a learner reads images.
- `ConstantRewardEnv`: constant observation, reward `reward` every step, episodes of `max_episode_steps`
  steps. With `terminate` the episode ends by termination after one step, so V = Q = reward; without it
  the time limit truncates, and a learner that bootstraps on truncation (as it must) learns
  V = Q = reward / (1 − γ), while one that treats truncation as termination learns less.
- `CountdownEnv`: episodes of a random length (1 to `longest` steps) whatever the action: tests what depends on
  when episodes end, as an evaluation that stops once every episode has.
- `HostCheckedEnv`: `CountdownEnv`'s fixed-length twin whose step `fault_at` of every episode records a fault
  that only the host raises on, as MJX Warp's dropped contacts: at that step, or once in `checked` after steps
  traced under `deferred_step_checks`. Tests who checks faults, and how often.
"""

import collections

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax.experimental import io_callback

from jaxarm.envs.base import Env, EnvSpec, EnvState, Transition, step_checks_deferred
from jaxarm.envs.observation import IMAGE


@struct.dataclass
class ProbeSim:
    """Probe state: what the episode shows (fixed within an episode): the target, for `TargetActionEnv`."""

    obs: jax.Array


@struct.dataclass
class TargetActionParams:
    """target_range: targets are uniform in ±target_range per action dim; max_episode_steps: time limit."""

    target_range: jax.Array
    max_episode_steps: jax.Array


class TargetActionEnv(Env[TargetActionParams, ProbeSim]):
    """One-step episodes: a random target in ±target_range, shown as obs = obs_offset + obs_scale · target;
    reward −Σ(a − target)², then terminated."""

    def __init__(self, action_size: int = 1, obs_offset: float = 0.0, obs_scale: float = 1.0):
        self.spec = EnvSpec(observation_shape=(action_size,), action_shape=(action_size,))
        self.obs_offset = obs_offset
        self.obs_scale = obs_scale

    def default_params(self) -> TargetActionParams:
        return TargetActionParams(target_range=jnp.array(0.5, jnp.float32), max_episode_steps=jnp.array(1, jnp.int32))

    def _reset(self, key, params):
        target = jax.random.uniform(
            key, self.spec.action_shape, minval=-params.target_range, maxval=params.target_range
        )
        return ProbeSim(obs=target), self.obs_offset + self.obs_scale * target, ()

    def _transition(self, sim, action, params):
        return Transition(
            sim=sim,
            obs=self.obs_offset + self.obs_scale * sim.obs,
            reward=-jnp.sum(jnp.square(action - sim.obs)),
            terminated=jnp.ones((), jnp.bool_),
            success=jnp.ones((), jnp.bool_),
            info=(),
        )


@struct.dataclass
class ConstantRewardParams:
    """reward: per-step reward; terminate: end every episode by termination after one step (bool);
    max_episode_steps: time limit (truncation) when not terminating."""

    reward: jax.Array
    terminate: jax.Array
    max_episode_steps: jax.Array


class ConstantRewardEnv(Env[ConstantRewardParams, ProbeSim]):
    """Observation always [1], any action, reward `reward` every step; see the module docstring for values."""

    spec = EnvSpec(observation_shape=(1,), action_shape=(1,))

    def default_params(self) -> ConstantRewardParams:
        return ConstantRewardParams(
            reward=jnp.array(1.0, jnp.float32), terminate=jnp.array(False), max_episode_steps=jnp.array(5, jnp.int32)
        )

    def _reset(self, key, params):
        obs = jnp.ones((1,), jnp.float32)
        return ProbeSim(obs=obs), obs, ()

    def _transition(self, sim, action, params):
        return Transition(
            sim=sim,
            obs=sim.obs,
            reward=params.reward.astype(jnp.float32),
            terminated=params.terminate,
            success=params.terminate,
            info=(),
        )


@struct.dataclass
class ImageTargetSim:
    """The episode's target [1] (−0.5 or +0.5) and the image that shows it."""

    target: jax.Array
    image: jax.Array


class ImageTargetEnv(Env[TargetActionParams, ImageTargetSim]):
    """One-step episodes observing {"image": uint8 [R, R, 1]}, all 0 for target −0.5 and all 255 for +0.5;
    reward −(a − target)², then terminated."""

    def __init__(self, resolution: int = 8):
        self.resolution = resolution
        image = jax.ShapeDtypeStruct((resolution, resolution, 1), jnp.uint8)
        self.spec = EnvSpec(observation_parts={IMAGE: image}, action_shape=(1,))

    def default_params(self) -> TargetActionParams:
        return TargetActionParams(target_range=jnp.array(0.5, jnp.float32), max_episode_steps=jnp.array(1, jnp.int32))

    def image(self, bright: jax.Array) -> jax.Array:
        return jnp.full((self.resolution, self.resolution, 1), 255 * bright, jnp.uint8)

    def _reset(self, key, params):
        bright = jax.random.bernoulli(key)
        sim = ImageTargetSim(
            target=jnp.where(bright, params.target_range, -params.target_range)[None], image=self.image(bright)
        )
        return sim, {IMAGE: sim.image}, ()

    def _transition(self, sim, action, params):
        return Transition(
            sim=sim,
            obs={IMAGE: sim.image},
            reward=-jnp.sum(jnp.square(action - sim.target)),
            terminated=jnp.ones((), jnp.bool_),
            success=jnp.ones((), jnp.bool_),
            info=(),
        )


@struct.dataclass
class CountdownParams:
    """longest: episodes last 1 to `longest` steps; max_episode_steps: time limit."""

    longest: jax.Array
    max_episode_steps: jax.Array


class CountdownEnv(Env[CountdownParams, ProbeSim]):
    """Episodes of a random length: obs [1] the steps left, reward 1 a step, terminated when none is left."""

    spec = EnvSpec(observation_shape=(1,), action_shape=(1,))

    def default_params(self) -> CountdownParams:
        return CountdownParams(longest=jnp.array(6, jnp.int32), max_episode_steps=jnp.array(20, jnp.int32))

    def _reset(self, key, params):
        left = jax.random.randint(key, (1,), 1, params.longest + 1).astype(jnp.float32)
        return ProbeSim(obs=left), left, ()

    def _transition(self, sim, action, params):
        left = sim.obs - 1.0
        return Transition(
            sim=ProbeSim(obs=left),
            obs=left,
            reward=jnp.ones((), jnp.float32),
            terminated=left[0] <= 0.0,
            success=left[0] <= 0.0,
            info=(),
        )


HOST_CHECKS: collections.Counter[str] = collections.Counter()
"""How often `HostCheckedEnv`'s host checks ran: "step" (a step's own check) and "checked" (`checked`'s)."""


def _raise_on_faults(faults: np.ndarray, kind: str) -> None:
    """Host side of `HostCheckedEnv`'s checks: a RuntimeError if any of the [...] faults is set; counted."""
    HOST_CHECKS[kind] += 1
    if np.any(faults):
        raise RuntimeError(f"probe fault in {int(np.count_nonzero(faults))} envs")


def _no_fault_in_step(faults: np.ndarray) -> np.ndarray:
    """Host side of a step's own check: [...] faults -> all True, or a RuntimeError."""
    _raise_on_faults(faults, "step")
    return np.ones(faults.shape, np.bool_)


@struct.dataclass
class HostCheckedSim:
    """step: [] int32 steps taken in the episode; faults: [] int32 faults recorded since the first reset."""

    step: jax.Array
    faults: jax.Array


@struct.dataclass
class HostCheckedParams:
    """fault_at: the episode step (from 0) that records a fault, −1 for none; max_episode_steps: time limit."""

    fault_at: jax.Array
    max_episode_steps: jax.Array


class HostCheckedEnv(Env[HostCheckedParams, HostCheckedSim]):
    """Observation [1] the episode's step, reward 1 a step, episodes truncated at `max_episode_steps`; the step
    numbered `fault_at` records a fault, raised on by the host (see the module docstring)."""

    spec = EnvSpec(observation_shape=(1,), action_shape=(1,))

    def default_params(self) -> HostCheckedParams:
        return HostCheckedParams(fault_at=jnp.array(-1, jnp.int32), max_episode_steps=jnp.array(4, jnp.int32))

    def _reset(self, key, params):
        sim = HostCheckedSim(step=jnp.zeros((), jnp.int32), faults=jnp.zeros((), jnp.int32))
        return sim, jnp.zeros((1,), jnp.float32), ()

    def _transition(self, sim, action, params):
        fault = (sim.step == params.fault_at).astype(jnp.int32)
        step = sim.step + 1
        if not step_checks_deferred():
            fine = jax.pure_callback(
                _no_fault_in_step, jax.ShapeDtypeStruct((), jnp.bool_), fault, vmap_method="expand_dims"
            )
            step = jnp.where(fine, step, -1)
        return Transition(
            sim=HostCheckedSim(step=step, faults=sim.faults + fault),
            obs=step.astype(jnp.float32)[None],
            reward=jnp.ones((), jnp.float32),
            terminated=jnp.zeros((), jnp.bool_),
            success=jnp.zeros((), jnp.bool_),
            info=(),
        )

    def carried_over(self, ended: HostCheckedSim, fresh: HostCheckedSim) -> HostCheckedSim:
        return fresh.replace(faults=ended.faults + fresh.faults)

    def checked(self, state: EnvState[HostCheckedSim]) -> EnvState[HostCheckedSim]:
        io_callback(lambda faults: _raise_on_faults(faults, "checked"), None, state.sim.faults)
        return state
