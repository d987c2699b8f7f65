"""Wrappers that keep the env contract: auto-reset and vmap over a batch of envs.

Episode statistics are kept by `Env.step` itself (`state.episode`, `state.last_episode`), so every env,
wrapped or not, reports the same numbers.
"""

import warnings

import jax
import jax.numpy as jnp

from jaxarm.envs.base import Env, EnvSpec, EnvState


class Wrapper:
    """Forwards the contract to an inner env; subclasses override what they change."""

    def __init__(self, env):
        self.env = env

    @property
    def spec(self) -> EnvSpec:
        return self.env.spec

    @property
    def unwrapped(self) -> Env:
        return getattr(self.env, "unwrapped", self.env)

    def default_params(self):
        return self.env.default_params()

    def reset(self, key: jax.Array, params) -> EnvState:
        return self.env.reset(key, params)

    def step(self, state: EnvState, action: jax.Array, params) -> EnvState:
        return self.env.step(state, action, params)


class AutoReset(Wrapper):
    """Starts a new episode inside `step` whenever the last one ended.

    After a done step, `obs`, `sim`, `step_count` and `episode` belong to the new episode, while `reward`,
    `terminated`, `truncated`, `final_obs` (the observation the episode ended on), `last_episode` and `info`
    describe the step that ended it.
    """

    def step(self, state: EnvState, action: jax.Array, params) -> EnvState:
        stepped = self.env.step(state, action, params)
        # The reset is computed for every env (vmap turns a branch into a select), so it must be cheap: it
        # draws from the carried key, which only advances when an episode ends. Random numbers dominated
        # the cost of a step (threefry hashes), so no extra split happens here.
        fresh = self.env.reset(stepped.key, params)
        done = stepped.done

        def pick(new, old):
            return jnp.where(done, new, old)

        return stepped.replace(
            sim=jax.tree.map(pick, fresh.sim, stepped.sim),
            obs=jax.tree.map(pick, fresh.obs, stepped.obs),
            step_count=pick(fresh.step_count, stepped.step_count),
            episode=jax.tree.map(pick, fresh.episode, stepped.episode),
            key=pick(fresh.key, stepped.key),
        )


class VmapEnv(Wrapper):
    """A batch of `num_envs` independent envs; states and actions gain a leading [num_envs] axis.

    Args:
      env: the env (or wrapped env) to batch.
      num_envs: batch size B.
      batched_params: if True, every params leaf has a leading [B] axis (per-env domain randomisation);
        otherwise one params pytree is shared by all envs.
    """

    def __init__(self, env, num_envs: int, batched_params: bool = False):
        super().__init__(env)
        self.num_envs = num_envs
        self.params_axis = 0 if batched_params else None
        limit = getattr(self.unwrapped, "cpu_max_envs", None)
        if limit is not None and num_envs > limit and jax.default_backend() == "cpu":
            warnings.warn(
                f"{type(self.unwrapped).__name__} with {num_envs} envs on the CPU: above {limit} envs jaxlib's CPU "
                f"runtime has deadlocked on it (see the README); the run may hang",
                stacklevel=2,
            )

    def reset(self, key: jax.Array, params) -> EnvState:
        keys = jax.random.split(key, self.num_envs)
        return jax.vmap(self.env.reset, in_axes=(0, self.params_axis))(keys, params)

    def step(self, state: EnvState, action: jax.Array, params) -> EnvState:
        return jax.vmap(self.env.step, in_axes=(0, 0, self.params_axis))(state, action, params)
