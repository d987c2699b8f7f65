"""A jaxarm env (with its params) as a `brax.envs.base.Env`, so that brax's own PPO and SAC train it unchanged.

The jaxarm `EnvState` is the brax State's `pipeline_state`; `obs`, `reward` and `done` are copied out of it.
brax's training wrappers (`brax.envs.training.wrap`: Vmap, then EpisodeWrapper for the time limit, then
AutoResetWrapper) would time-limit and reset the env a second time, so the adapter runs in one of two
modes; `auto_reset` picks one, and a wrong pairing raises at trace time:

- `auto_reset=True` (default): ours on both counts. The jaxarm time limit (`params.max_episode_steps`) and
  `jaxarm.envs.AutoReset` run inside the adapter, so every new episode is freshly sampled (arm2d: a new
  random goal), exactly as jaxarm's own trainers see it. done = terminated | truncated,
  `info['truncation']` = `info['time_out']` = truncated (brax's GAE masks those steps instead of treating
  them as terminal; `bootstrap_on_timeout=True` reads `time_out`), and
  the adapter keeps brax's episode bookkeeping itself (`info['steps']`, `info['episode_done']`,
  `info['episode_metrics']`). Train with `wrap_env_fn=wrap_for_training`, which only vmaps; pass
  `episode_length=params.max_episode_steps` (brax's evaluator runs that many steps per eval episode).
- `auto_reset=False`: brax's way. The adapter neither resets nor reports the time limit (done = terminated),
  brax's default wrappers do both: pass `episode_length=params.max_episode_steps`. brax's AutoResetWrapper
  returns each env to its own first state, so an env replays the same start (arm2d: the same goal) after
  every reset, unlike jaxarm's trainers; use it to compare with brax envs on brax's terms.

`metrics['success']` is 1.0 on the step that ends a successful episode, so brax's episode sums of it (its
evaluator's `eval/episode_success`) are success rates. Actions from brax's tanh policies lie in [-1, 1];
the jaxarm env clips them to its own bounds. Constructing a `BraxEnv` puts back `jax.device_put_replicated`,
which brax's trainers call and jax >= 0.10 removed (`brax_compat`). Not thread-safe or numpy-facing: see
`gymnasium_env` for that.
"""

from typing import Any

import jax
import jax.numpy as jnp

from jaxarm._runtime import import_mjx_quietly

import_mjx_quietly()  # before brax, which imports mujoco.mjx

from brax.envs import base as brax_base  # noqa: E402
from brax.envs.wrappers.training import VmapWrapper  # noqa: E402

from jaxarm.envs import AutoReset, EnvState  # noqa: E402
from jaxarm.interop.brax_compat import install_device_put_replicated  # noqa: E402

# Keys the brax AutoResetWrapper adds to `info`; seeing one means brax is resetting this env too.
_BRAX_AUTO_RESET_KEY = "first_pipeline_state"


class BraxEnv(brax_base.Env):
    """`env` with fixed `params` behind brax's Env interface; see the module docstring for `auto_reset`.

    Args:
      env: a jaxarm env (or wrapped env) without auto-reset.
      params: the env params every episode uses (a pytree of arrays; fixed for the adapter's life).
      auto_reset: True: jaxarm time limit and auto-reset inside, train with `wrap_for_training`;
        False: brax's EpisodeWrapper/AutoResetWrapper do both.
    """

    def __init__(self, env, params, auto_reset: bool = True):
        # brax's trainers call jax.device_put_replicated, gone in jax >= 0.10: put it back before they can.
        install_device_put_replicated()
        self.env = env
        self.params = params
        self.auto_reset = auto_reset
        self._stepper = AutoReset(env) if auto_reset else env

    @property
    def observation_size(self) -> brax_base.ObservationSize:
        """The flat observation's size, or each part's shape for a dict observation (brax's convention)."""
        spec = self.env.spec
        if spec.flat_observation:
            return spec.observation_size
        return {name: part.shape for name, part in spec.observation_parts.items()}

    @property
    def action_size(self) -> int:
        return self.env.spec.action_size

    @property
    def backend(self) -> str:
        return "jaxarm"

    @property
    def max_episode_steps(self) -> int:
        """The jaxarm time limit; pass it to brax's trainers as `episode_length`."""
        return int(self.params.max_episode_steps)

    def reset(self, rng: jax.Array) -> brax_base.State:
        env_state = self.env.reset(rng, self.params)
        zero = jnp.zeros((), jnp.float32)
        info = self._episode_info(env_state) if self.auto_reset else {}
        return brax_base.State(
            pipeline_state=env_state,
            obs=env_state.obs,
            reward=zero,
            done=zero,
            metrics={"success": zero},
            info=info,
        )

    def step(self, state: brax_base.State, action: jax.Array) -> brax_base.State:
        if self.auto_reset and _BRAX_AUTO_RESET_KEY in state.info:
            raise ValueError(
                "BraxEnv(auto_reset=True) is being reset by brax's AutoResetWrapper as well: train with "
                "wrap_env_fn=jaxarm.interop.brax_env.wrap_for_training, or build BraxEnv(auto_reset=False)"
            )
        env_state = self._stepper.step(state.pipeline_state, action, self.params)
        done = env_state.done if self.auto_reset else env_state.terminated
        info = {**state.info, **self._episode_info(env_state)} if self.auto_reset else state.info
        return state.replace(
            pipeline_state=env_state,
            obs=env_state.obs,
            reward=env_state.reward,
            done=done.astype(jnp.float32),
            # Keep keys wrappers added (brax's EvalWrapper adds 'reward'): the structure is a scan carry.
            metrics={**state.metrics, "success": (env_state.done & env_state.last_episode.success).astype(jnp.float32)},
            info=info,
        )

    @staticmethod
    def _episode_info(env_state: EnvState) -> dict[str, Any]:
        """What brax's EpisodeWrapper would keep, read from the jaxarm state (auto-reset mode only).

        On a done step the running episode has already been replaced by the next one's, so the finished
        episode's numbers come from `last_episode`.
        """
        done = env_state.done

        def finished_or_running(finished, running):
            return jnp.where(done, finished, running).astype(jnp.float32)

        length = finished_or_running(env_state.last_episode.length, env_state.episode.length)
        truncated = env_state.truncated.astype(jnp.float32)
        return {
            "truncation": truncated,
            "time_out": truncated,  # read by brax PPO's bootstrap_on_timeout=True
            "steps": length,
            "episode_done": done.astype(jnp.float32),
            "episode_metrics": {
                "sum_reward": finished_or_running(env_state.last_episode.return_, env_state.episode.return_),
                "length": length,
                "success": finished_or_running(env_state.last_episode.success, env_state.episode.success),
            },
        }


def wrap_for_training(
    env: BraxEnv, episode_length: int = 1000, action_repeat: int = 1, randomization_fn=None
) -> brax_base.Wrapper:
    """brax's `wrap_env_fn` for a `BraxEnv(auto_reset=True)`: vmap only, time limit and resets stay jaxarm's.

    Same signature as `brax.envs.training.wrap`. `episode_length` must equal the env's time limit (brax's
    evaluator runs `episode_length` steps per eval episode); action repeat and brax-side domain
    randomisation are not supported (randomise through jaxarm params instead).
    """
    if not isinstance(env, BraxEnv) or not env.auto_reset:
        raise ValueError("wrap_for_training needs a BraxEnv(auto_reset=True); use brax's own wrap otherwise")
    if episode_length != env.max_episode_steps:
        raise ValueError(
            f"episode_length={episode_length} must equal the env's max_episode_steps={env.max_episode_steps}"
        )
    if action_repeat != 1 or randomization_fn is not None:
        raise ValueError("wrap_for_training supports neither action_repeat != 1 nor randomization_fn")
    return VmapWrapper(env)
