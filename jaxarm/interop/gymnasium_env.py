"""Any jaxarm env as a Gymnasium env: `GymnasiumEnv` (one env) and `GymnasiumVectorEnv` (a batch), numpy in/out.

Both hold the jaxarm state on the JAX device and call jit-compiled `reset`/`step` (compiled once per adapter;
params are an argument, not a constant). Actions arrive from outside jit, so they are validated with
`jaxarm.envs.check_action` (a ValueError names a wrong shape or a NaN/inf) before anything is stepped.

Seeding follows Gymnasium: `reset(seed=s)` seeds the adapter's `np_random`, and every reset (seeded or not) draws
its JAX key from it, so the same seed gives the same episodes; the vector env's `reset(seed=[s0, s1, ...])` gives
env i the key of its own seed (None: one drawn from `np_random`). Params are checked against their declared ranges
when an adapter is made and at every reset (`params` may be replaced in between). Observation spaces are unbounded
Boxes (jaxarm envs do not declare observation bounds; `check_env` warns about that and nothing else); a dict
observation (camera images) is a Dict space of such Boxes, its uint8 parts bounded by 0 and 255.

`render()` returns an RGB frame (uint8 [H, W, 3]) from the jaxarm env's own `render(state, params)` when
the env has one; `render_mode` must then be "rgb_array".

What the vector env's auto-reset does (Gymnasium's `AutoresetMode.SAME_STEP`): on a step that ends an
episode, the returned observation already belongs to the next episode; `infos["final_obs"]` [B, O] holds
the observation each env reached before any reset (equal to the returned one where `infos["_final_obs"]`
is False), and `infos["episode"]` holds the finished episodes' return `r`, length `l` and `success`, valid
where `infos["_episode"]` is True (the RecordEpisodeStatistics convention).

Importing this module registers every jaxarm env with Gymnasium as `jaxarm/<Name>-v0`, the name in CamelCase
(`gymnasium_id`: arm2d is `jaxarm/Arm2d-v0`, panda_sort `jaxarm/PandaSort-v0`), so that
`gymnasium.make("jaxarm/Arm2d-v0", render_mode=..., params=..., **env_kwargs)` builds a `GymnasiumEnv`.
"""

import dataclasses
import functools
from collections.abc import Sequence

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from jaxarm import envs
from jaxarm.envs import AutoReset, Env, EnvState, VmapEnv, check_action
from jaxarm.envs.base import check_concrete_params

NAMESPACE = "jaxarm"


def _observation_space(env) -> gym.spaces.Space:
    """An unbounded float32 Box, or for a dict observation a Dict of Boxes (uint8 parts bounded by 0 and 255)."""

    def box(part: jax.ShapeDtypeStruct) -> gym.spaces.Box:
        dtype = np.dtype(part.dtype)
        if np.issubdtype(dtype, np.integer):
            bounds = np.iinfo(dtype)
            return gym.spaces.Box(int(bounds.min), int(bounds.max), part.shape, dtype)
        return gym.spaces.Box(-np.inf, np.inf, part.shape, dtype)

    spec = env.spec
    if spec.flat_observation:
        return box(spec.observation)
    return gym.spaces.Dict({name: box(part) for name, part in spec.observation_parts.items()})


def _numpy(tree):
    """A pytree of device arrays as writable numpy arrays (Gymnasium callers may modify what they get)."""
    return jax.tree.map(np.array, jax.device_get(tree))


def _action_space(env) -> gym.spaces.Box:
    spec = env.spec
    return gym.spaces.Box(spec.action_low, spec.action_high, spec.action_shape, np.float32)


def _can_render(env) -> bool:
    unwrapped = getattr(env, "unwrapped", env)
    return type(unwrapped).render is not Env.render


def _render_modes(env, render_mode: str | None) -> list[str]:
    modes = ["rgb_array"] if _can_render(env) else []
    if render_mode is not None and render_mode not in modes:
        raise ValueError(f"render_mode {render_mode!r} is not supported by this env; supported: {modes}")
    return modes


def _draw_key(np_random: np.random.Generator) -> jax.Array:
    return jax.random.PRNGKey(np_random.integers(0, 2**31 - 1))


def _env_info(state: EnvState) -> dict:
    """The env's per-step diagnostics (its `info` dataclass) and the episode's success so far, as numpy."""
    info = {"success": state.episode.success}
    if dataclasses.is_dataclass(state.info):
        info.update({field.name: getattr(state.info, field.name) for field in dataclasses.fields(state.info)})
    return jax.tree.map(np.array, jax.device_get(info))


class GymnasiumEnv(gym.Env):
    """One jaxarm env behind `gymnasium.Env`.

    Args:
      env: a jaxarm env (no auto-reset: Gymnasium's caller resets).
      params: env params; defaults to `env.default_params()`.
      render_mode: None or "rgb_array" (only if the env can render).
    """

    def __init__(self, env, params=None, render_mode: str | None = None):
        self.jax_env = env
        self.params = env.default_params() if params is None else params
        check_concrete_params(self.params)
        self.metadata = {"render_modes": _render_modes(env, render_mode), "render_fps": 30}
        self.render_mode = render_mode
        self.observation_space = _observation_space(env)
        self.action_space = _action_space(env)
        self._reset = jax.jit(env.reset)
        self._step = jax.jit(env.step)
        self.state: EnvState | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        check_concrete_params(self.params)
        self.state = self._reset(_draw_key(self.np_random), self.params)
        return _numpy(self.state.obs), _env_info(self.state)

    def step(self, action):
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        action = check_action(action, self.jax_env.spec)
        self.state = self._step(self.state, jnp.asarray(action), self.params)
        obs, reward, terminated, truncated = jax.device_get(
            (self.state.obs, self.state.reward, self.state.terminated, self.state.truncated)
        )
        return _numpy(obs), float(reward), bool(terminated), bool(truncated), _env_info(self.state)

    def render(self):
        if self.render_mode is None:
            return None
        if self.state is None:
            raise RuntimeError("call reset() before render()")
        return self.jax_env.render(self.state, self.params)


class GymnasiumVectorEnv(VectorEnv):
    """`num_envs` auto-resetting jaxarm envs behind `gymnasium.vector.VectorEnv` (SAME_STEP auto-reset).

    Args:
      env: a jaxarm env (auto-reset is added here).
      num_envs: batch size B.
      params: env params shared by all envs; defaults to `env.default_params()`.
      render_mode: None or "rgb_array"; `render()` then returns one frame per env.
    """

    def __init__(self, env, num_envs: int, params=None, render_mode: str | None = None):
        self.jax_env = env
        self.num_envs = num_envs
        self.params = env.default_params() if params is None else params
        check_concrete_params(self.params)
        self.metadata = {
            "render_modes": _render_modes(env, render_mode),
            "render_fps": 30,
            "autoreset_mode": AutoresetMode.SAME_STEP,
        }
        self.render_mode = render_mode
        self.single_observation_space = _observation_space(env)
        self.single_action_space = _action_space(env)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        batch = VmapEnv(AutoReset(env), num_envs)
        self._batch_action_spec = dataclasses.replace(env.spec, action_shape=(num_envs,) + env.spec.action_shape)
        self._reset = jax.jit(batch.reset)
        self._reset_each = jax.jit(jax.vmap(batch.env.reset, in_axes=(0, None)))  # keys [B, 2]
        self._step = jax.jit(batch.step)
        self.state: EnvState | None = None

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict | None = None):
        check_concrete_params(self.params)
        if seed is None or isinstance(seed, (int, np.integer)):
            super().reset(seed=seed)
            self.state = self._reset(_draw_key(self.np_random), self.params)
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset(seed=...) got {len(seeds)} seeds for {self.num_envs} envs")
            keys = [_draw_key(self.np_random) if each is None else jax.random.PRNGKey(each) for each in seeds]
            self.state = self._reset_each(jnp.stack(keys), self.params)
        return _numpy(self.state.obs), {}

    def step(self, actions):
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        actions = check_action(actions, self._batch_action_spec)
        self.state = self._step(self.state, jnp.asarray(actions), self.params)
        state = self.state
        last = state.last_episode
        obs, reward, terminated, truncated, final_obs, done, episode = jax.tree.map(
            np.array,
            jax.device_get(
                (
                    state.obs,
                    state.reward,
                    state.terminated,
                    state.truncated,
                    state.final_obs,
                    state.done,
                    {"r": last.return_, "l": last.length, "success": last.success},
                )
            ),
        )
        infos = {"final_obs": final_obs, "_final_obs": done, "episode": episode, "_episode": done}
        return obs, reward, terminated, truncated, infos

    def render(self):
        if self.render_mode is None:
            return None
        if self.state is None:
            raise RuntimeError("call reset() before render()")
        states = jax.device_get(self.state)
        return tuple(
            self.jax_env.render(jax.tree.map(lambda leaf, i=i: leaf[i], states), self.params)
            for i in range(self.num_envs)
        )


def gymnasium_id(name: str) -> str:
    """The Gymnasium id of jaxarm env `name`: "arm2d_pixels" -> "jaxarm/Arm2dPixels-v0"."""
    return f"{NAMESPACE}/{''.join(part[:1].upper() + part[1:] for part in name.split('_'))}-v0"


def make_registered(name: str, render_mode: str | None = None, params=None, **env_kwargs) -> GymnasiumEnv:
    """`gymnasium.make`'s entry point for jaxarm env `name`: `env_kwargs` go to its constructor."""
    return GymnasiumEnv(envs.make(name, **env_kwargs), params, render_mode)


def register_all() -> None:
    """Registers every jaxarm env with Gymnasium under `gymnasium_id` (ids already registered are kept)."""
    for name in envs.names():
        if gymnasium_id(name) not in gym.registry:
            gym.register(gymnasium_id(name), entry_point=functools.partial(make_registered, name))


register_all()
