"""Deterministic evaluation of a policy on fresh episodes, and episode recording for videos."""

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxarm.envs import EnvState, VmapEnv, deferred_step_checks


@struct.dataclass
class EvalResult:
    """Per-episode results, each [episodes]: return, length, success (bool), and the env's info pytree of
    each episode's last step (e.g. the sorter's object counts, the peg's final distance)."""

    returns: jax.Array
    lengths: jax.Array
    successes: jax.Array
    final_info: Any

    def summary(self) -> dict:
        """Plain-Python summary for eval.json; the final info's scalar leaves as means under "final_info/..."."""
        info = {
            "final_info/" + jax.tree_util.keystr(path, simple=True, separator="/"): float(jnp.mean(leaf))
            for path, leaf in jax.tree_util.tree_leaves_with_path(self.final_info)
            if leaf.ndim == 1
        }
        return {
            "episodes": int(self.returns.shape[0]),
            "success_rate": float(jnp.mean(self.successes)),
            "return_mean": float(jnp.mean(self.returns)),
            "return_std": float(jnp.std(self.returns)),
            "length_mean": float(jnp.mean(self.lengths)),
            **info,
        }


def episode_step(env, env_params, policy: Callable[[Any], jax.Array], episodes: int):
    """One step of `episodes` envs without auto-reset, `policy: obs [B, ...] -> action [B, A]`: an env that
    has finished stays frozen at its last state (its `done` stays true). Returns (the batch env, step)."""
    batch = VmapEnv(env, episodes)

    def step(state: EnvState) -> EnvState:
        stepped = batch.step(state, policy(state.obs), env_params)
        finished = state.done

        def keep_finished(old, new):
            return jnp.where(finished.reshape(finished.shape + (1,) * (new.ndim - 1)), old, new)

        return jax.tree.map(keep_finished, state, stepped)

    return batch, step


def rollout_episodes(
    env, env_params, policy: Callable[[Any], jax.Array], key, episodes: int, max_steps: int
) -> EnvState:
    """Runs `episodes` fresh episodes to their end (no auto-reset) with `policy: obs [B, ...] -> action [B, A]`.

    Returns the env states after every step, [max_steps, episodes, ...]; an env that has finished stays
    frozen at its last state (its `done` stays true).
    """
    batch, step = episode_step(env, env_params, policy, episodes)

    def body(state, _):
        state = step(state)
        return state, state

    _, states = jax.lax.scan(body, batch.reset(key, env_params), None, length=max_steps)
    return states


def evaluate(env, env_params, policy, key, episodes: int) -> EvalResult:
    """Runs `episodes` fresh episodes with a deterministic `policy` and returns their results (jit-able).

    Only the last state is kept (not every step's, as `rollout_episodes` does): camera observations of a
    thousand episodes over every step would not fit in memory. Stepping stops once every episode has ended (at
    the latest after the time limit): a finished env stays frozen, so the results are those of stepping the
    whole time limit (up to the float rounding of another compiled program), and a policy whose episodes end
    early is evaluated in a fraction of it.
    """
    max_steps = int(env_params.max_episode_steps)
    batch, step = episode_step(env, env_params, policy, episodes)

    def running(carry: tuple[jax.Array, EnvState]) -> jax.Array:
        steps, state = carry
        return (steps < max_steps) & ~jnp.all(state.done)

    with deferred_step_checks():  # checked once, at the end
        _, final = jax.lax.while_loop(
            running, lambda carry: (carry[0] + 1, step(carry[1])), (jnp.int32(0), batch.reset(key, env_params))
        )
    final = batch.checked(final)
    return EvalResult(
        returns=final.episode.return_,
        lengths=final.episode.length,
        successes=final.episode.success,
        final_info=final.info,
    )
