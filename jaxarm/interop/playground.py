"""MuJoCo Playground's envs as jaxarm envs: `envs.make("playground:PandaPickCube")`, `env=playground:NAME` on the CLI.

`PlaygroundEnv(task, impl, privileged, **config_overrides)` wraps the Playground `MjxEnv` of that registry name and
keeps jaxarm's contract (jaxarm.envs.base), so jaxarm's learners, evaluation, sweeps, `randomize` and
`eval --perturb` run on it as on any other env:

- The time limit is ours: `params.max_episode_steps`, by default the task's `episode_length` (brax's EpisodeWrapper
  does this for Playground's own trainers). Playground's `done` (the box out of bounds, NaN physics) is
  `terminated`; `AutoReset` samples every new episode afresh with Playground's `reset`. Playground's own training
  wrapper (`BraxAutoResetWrapper`) resets data and observation only, so what a task accumulates in its `info` (the
  pick's `reached_box`, which turns on its box-to-target reward) outlives the episode; `carry_info` names the
  `info` keys a new episode keeps from the last here likewise.
- `impl` is chosen as the Panda envs choose theirs (`jaxarm.envs.panda.mjx_impl.resolve_impl`: "jax" by default,
  "warp", or "auto") and handed to Playground's config; its Warp buffers are Playground's own config keys
  (`naconmax`, `njmax`), overridable like any other (`env_kwargs.naconmax=...`).
- `success`: the task's own metric where it reports one (`SUCCESS_METRICS`, at any step); for the pick-cube tasks,
  which report none, the box within `BOX_SUCCESS_RADIUS` of its target at the episode's time limit
  (`END_CRITERIA`); never for any other task.
- A dict observation's `privileged_state` is our `privileged` part (for an asymmetric critic) with
  `privileged=True`, and left out otherwise; a dict left with `state` alone is observed as that flat array.
- Params scale the physics of Playground's model per env (`PlaygroundParams`), swapped in for each call as
  Playground's own domain randomisation does (its `BraxDomainRandomizationVmapWrapper`).

Playground clones MuJoCo Menagerie from the internet when it first loads a task; importing this module points it
at the copy of menagerie's Franka Panda in assets/ instead (`use_vendored_menagerie`), so the Franka tasks build
offline. Tasks of other robots still need menagerie at Playground's own path.
"""

import contextlib
import dataclasses
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct

from jaxarm._runtime import import_mjx_quietly

import_mjx_quietly()  # before Playground, which imports mujoco.mjx

try:
    from mujoco_playground import registry as playground_registry
    from mujoco_playground._src import mjx_env
except ImportError as error:  # the optional extra is absent
    raise ImportError(
        "jaxarm.interop.playground needs MuJoCo Playground: pip install -c constraints.txt -e '.[playground]'"
    ) from error

from mujoco import mjx  # noqa: E402
from mujoco.mjx._src.types import tree_path_to_attr_str  # noqa: E402
from mujoco.mjx.warp import types as warp_types  # noqa: E402

from jaxarm.envs.base import Env, EnvSpec, Observation, Transition  # noqa: E402
from jaxarm.envs.observation import PRIVILEGED  # noqa: E402
from jaxarm.envs.panda.mjx_impl import Impl, resolve_impl, silence_overflow_warnings  # noqa: E402
from jaxarm.envs.registry import closest_match_hint  # noqa: E402
from jaxarm.ranges import COUNT, POSITIVE, ranged  # noqa: E402

MENAGERIE = Path(__file__).parent / "assets" / "mujoco_menagerie"
"""Our copy of the part of MuJoCo Menagerie that Playground's Franka tasks load (its README says what changed)."""
BOX_SUCCESS_RADIUS = 0.02
"""Metres: a pick-cube episode succeeds when its box's centre ends within this distance of the target's."""
SUCCESS_METRICS = ("success", "reward/success")
"""Names under which a Playground task reports its own success in `metrics` (positive where it succeeds)."""
STATE = "state"
"""Playground's key of what its policy observes in a dict observation."""
PLAYGROUND_PRIVILEGED = "privileged_state"
"""Playground's key of what only its critic observes in a dict observation."""


def use_vendored_menagerie() -> None:
    """Points Playground at `MENAGERIE`: it reads `mjx_env.MENAGERIE_PATH` when it loads a task's assets, and
    clones menagerie there from the internet only where that path does not exist."""
    mjx_env.MENAGERIE_PATH = MENAGERIE


use_vendored_menagerie()


def box_at_target(mj_model: mujoco.MjModel) -> Callable[[mjx_env.State], jax.Array]:
    """A pick-cube task's criterion: [] bool, the body "box" within `BOX_SUCCESS_RADIUS` of `info["target_pos"]`."""
    box = mj_model.body("box").id

    def holds(state: mjx_env.State) -> jax.Array:
        return jnp.linalg.norm(state.data.xpos[box] - state.info["target_pos"]) < BOX_SUCCESS_RADIUS

    return holds


END_CRITERIA: Mapping[str, Callable[[mujoco.MjModel], Callable[[mjx_env.State], jax.Array]]] = {
    "PandaPickCube": box_at_target,
    "PandaPickCubeOrientation": box_at_target,
}
"""Tasks that report no success of their own -> the criterion judged at their episodes' time limit."""


@struct.dataclass
class PlaygroundParams:
    """What a user may randomise, sweep or perturb: the time limit and scales of the task's physics (1: as
    Playground builds it). Each is a scalar.

    Attributes:
      max_episode_steps: time limit, env steps (the task's `episode_length` by default).
      friction_scale: multiplies every geom's sliding friction.
      mass_scale: multiplies every body's mass and inertia.
      actuator_gain_scale: multiplies every actuator's gain and its position feedback (a position servo's kp).
    """

    max_episode_steps: jax.Array = ranged(allowed=COUNT)
    friction_scale: jax.Array = ranged(1.0, POSITIVE)
    mass_scale: jax.Array = ranged(1.0, POSITIVE)
    actuator_gain_scale: jax.Array = ranged(1.0, POSITIVE)


def quiet_model(model: mjx.Model, impl: Impl) -> mjx.Model:
    """`model`, whose kernels print no overflow lines where it steps on Warp (`impl`).

    Each Warp world prints a line whenever its solver stops at its iteration limit, which Playground's Franka
    tasks reach by design: ~5e5 lines (80-94 MB) in a 20M-env-step `ppo_playground_pick` run (H200). Only the
    printing goes; the simulation is unchanged."""
    return silence_overflow_warnings(model) if impl is Impl.WARP else model


def scaled_model(model: mjx.Model, params: PlaygroundParams) -> mjx.Model:
    """`model` with its friction, masses and actuator gains scaled by `params`."""
    return model.replace(
        geom_friction=model.geom_friction.at[:, 0].multiply(params.friction_scale),
        body_mass=model.body_mass * params.mass_scale,
        body_inertia=model.body_inertia * params.mass_scale,
        actuator_gainprm=model.actuator_gainprm.at[:, 0].multiply(params.actuator_gain_scale),
        actuator_biasprm=model.actuator_biasprm.at[:, 1].multiply(params.actuator_gain_scale),
    )


def shared_by_the_batch(path: jax.tree_util.KeyPath, state: mjx_env.State) -> bool:
    """Whether the leaf at `path` of `state` is one of MJX Warp's Data fields that every env of a batch shares (its
    contact buffer, counters and sizes: `mujoco.mjx.warp.types._BATCH_DIM`), which a vmap must leave unbatched."""
    if state.data.impl != mjx.Impl.WARP or path[0] != jax.tree_util.GetAttrKey("data"):
        return False
    return not warp_types._BATCH_DIM["Data"].get(tree_path_to_attr_str(path[1:]), True)


@dataclasses.dataclass(frozen=True)
class StateLayout:
    """Which arrays of a task's Playground state its sim keeps, one set per env: not those of size zero (a checkpoint,
    orbax, refuses them; an mjx.Data holds several, `act` of a model without activations), nor those MJX Warp shares
    over a batch (`shared_by_the_batch`: jaxarm's envs are vmapped whole, which would give every env its own), which
    are recomputed at every step. Those are put back as a state made once holds them.

    Attributes:
      treedef: the structure of the task's state.
      kept: per array of `treedef`, whether the sim keeps it.
      fixed: per array not kept, in order: zeros of its shape and dtype (a `jax.ShapeDtypeStruct`), or its value.
    """

    treedef: Any
    kept: tuple[bool, ...]
    fixed: tuple[Any, ...]

    @classmethod
    def of(cls, state: mjx_env.State) -> "StateLayout":
        """The layout of states like `state`, one env's, which gives the arrays not kept."""
        paths, treedef = jax.tree_util.tree_flatten_with_path(state)
        kept = tuple(leaf.size > 0 and not shared_by_the_batch(path, state) for path, leaf in paths)
        fixed = tuple(
            np.asarray(leaf) if np.any(leaf) else jax.ShapeDtypeStruct(leaf.shape, leaf.dtype)
            for (_, leaf), keep in zip(paths, kept, strict=True)
            if not keep
        )
        return cls(treedef, kept, fixed)

    def pack(self, state: mjx_env.State) -> tuple[jax.Array, ...]:
        """The arrays the sim keeps of `state` (with any leading batch axes), in order."""
        leaves, treedef = jax.tree.flatten(state)
        if treedef != self.treedef:
            raise ValueError(f"the task's state changed its structure from reset to step: {treedef} != {self.treedef}")
        return tuple(leaf for leaf, keep in zip(leaves, self.kept, strict=True) if keep)

    def unpack(self, arrays: tuple[jax.Array, ...]) -> mjx_env.State:
        """The state `pack` took `arrays` from, the arrays not kept put back without batch axes."""
        kept, fixed = iter(arrays), iter(self.fixed)

        def put_back(value: Any) -> jax.Array:
            if isinstance(value, jax.ShapeDtypeStruct):
                return jnp.zeros(value.shape, value.dtype)
            return jnp.asarray(value)

        return jax.tree.unflatten(self.treedef, [next(kept) if keep else put_back(next(fixed)) for keep in self.kept])


@struct.dataclass
class PlaygroundSim:
    """The env's sim: the non-empty arrays of Playground's state (`StateLayout`, `PlaygroundEnv.playground_state`
    rebuilds it) and the steps taken in its episode (for criteria judged at its end)."""

    arrays: tuple[jax.Array, ...]
    steps: jax.Array


def strongly_typed(tree: Any) -> Any:
    """`tree` with every leaf an array of its own dtype, not weakly typed: Playground starts some metrics as Python
    floats, and the state must keep one type from reset to step to be a scan carry."""
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.asarray(leaf).dtype), tree)


def config_keys(config: Any, prefix: str = "") -> list[str]:
    """Every key a Playground config takes as an override, nested ones dotted (`reward_config.scales.box_target`)."""
    keys = []
    for name, value in config.items():
        keys.append(prefix + name)
        if hasattr(value, "items"):
            keys.extend(config_keys(value, f"{prefix}{name}."))
    return keys


def observation(obs: mjx_env.Observation, privileged: bool) -> Observation:
    """A Playground observation as jaxarm's: a flat one as it is; of a dict, every part but `privileged_state`,
    which is the `privileged` part where `privileged` asks for it, and a dict left with `state` alone as that
    array. ValueError where `privileged` asks for a privileged state the observation lacks."""
    if privileged and not (isinstance(obs, Mapping) and PLAYGROUND_PRIVILEGED in obs):
        raise ValueError(f"the task's observation has no {PLAYGROUND_PRIVILEGED}: privileged=true has nothing to give")
    if not isinstance(obs, Mapping):
        return obs
    parts = {name: part for name, part in obs.items() if name != PLAYGROUND_PRIVILEGED}
    if privileged:
        parts[PRIVILEGED] = obs[PLAYGROUND_PRIVILEGED]
    return parts[STATE] if parts.keys() == {STATE} else parts


def carried_info_keys(carry_info: str | Sequence[str], info: Mapping[str, Any]) -> tuple[str, ...]:
    """The `info` keys named by `carry_info` (a comma-separated string, as the CLI gives it, or a sequence), in
    order. ValueError naming the keys `info` has for one it lacks."""
    listed = carry_info.split(",") if isinstance(carry_info, str) else carry_info
    names = tuple(name.strip() for name in listed if name.strip())
    for name in names:
        if name not in info:
            raise ValueError(f"carry_info: the task's info has no key {name!r} (it has {', '.join(sorted(info))})")
    return names


def checked_overrides(task: str, impl: Impl, overrides: Mapping[str, Any]) -> dict[str, Any]:
    """`overrides` of the Playground task `task`'s config, with `impl` where the config has one. KeyError naming the
    closest task for an unknown one, TypeError the closest key for one the config lacks; ValueError for a task that
    repeats its actions (the adapter steps once per action) or Warp asked of a task whose config has no impl."""
    known = playground_registry.ALL_ENVS
    if task not in known:
        raise KeyError(f"unknown Playground task {task!r}{closest_match_hint(task, known)}")
    config = playground_registry.get_default_config(task)
    keys = config_keys(config)
    for name in overrides:
        if name not in keys:
            raise TypeError(f"{task}'s config has no key {name!r}{closest_match_hint(name, keys)}")
    if config.get("action_repeat", 1) != 1:
        raise ValueError(f"{task} repeats each action {config.action_repeat} times; the adapter steps once")
    if "impl" in config:
        return {**overrides, "impl": impl.value}
    if impl != Impl.JAX:
        raise ValueError(f"{task}'s config has no impl to set: it steps MJX-JAX")
    return dict(overrides)


class PlaygroundEnv(Env[PlaygroundParams, PlaygroundSim]):
    """The Playground task `task` behind jaxarm's contract (see the module docstring).

    Args:
      task: Playground's registry name of the task, e.g. "PandaPickCube".
      impl: MJX implementation: "jax", "warp" or "auto" (`jaxarm.envs.panda.mjx_impl.Impl`).
      privileged: observe Playground's `privileged_state` as the `privileged` part, for an asymmetric critic
        (only for tasks whose observation has one).
      carry_info: keys of the task's `info` that a new episode keeps from the one before it, as Playground's
        training wrapper keeps all of them (comma-separated or a sequence; none by default).
      config_overrides: Playground config keys (dotted where nested) -> values.

    Attributes:
      task: the Playground registry name.
      playground: the Playground `MjxEnv`.
      impl: the MJX implementation in use.
      carry_info: the `info` keys a new episode keeps from the one before it, in order.
      mj_model: the task's compiled MuJoCo model.
    """

    uses_mjx = True
    draws_with_gl = True

    def __init__(
        self,
        task: str,
        impl: str = Impl.JAX,
        privileged: bool = False,
        carry_info: str | Sequence[str] = (),
        **config_overrides: Any,
    ):
        self.task = task
        self.impl = resolve_impl(impl)
        self.privileged = privileged
        self.playground = playground_registry.load(
            task, config_overrides=checked_overrides(task, self.impl, config_overrides)
        )
        self.mj_model = self.playground.mj_model
        self.episode_length = int(self.playground._config.episode_length)
        # Playground put its model on jax.devices()[0]: process 0's device in every process of a run of several
        # (--distributed), where no other process may read it or close over it. Put again from the MjModel on this
        # process's own device, in every run so that all see one model (a task that edits its MjModel after
        # Playground put it, as PandaOpenCabinet does the hand's conaffinity, steps with the edit here).
        self._nominal_model = quiet_model(
            mjx.put_model(self.mj_model, jax.local_devices()[0], impl=self.impl.value), self.impl
        )
        self.playground._mjx_model = self._nominal_model
        self._end_criterion = END_CRITERIA[task](self.mj_model) if task in END_CRITERIA else None
        state = jax.jit(lambda key: strongly_typed(self.playground.reset(key)))(jax.random.key(0))
        self.layout = StateLayout.of(state)
        self.carry_info = carried_info_keys(carry_info, state.info)
        self.spec = self._make_spec(observation(state.obs, self.privileged))

    def _make_spec(self, obs: Any) -> EnvSpec:
        """The spec of observations shaped as `obs` (their shapes and dtypes) and of the task's actions."""
        action_shape = (self.playground.action_size,)
        if isinstance(obs, Mapping):
            return EnvSpec(observation_parts=dict(obs), action_shape=action_shape)
        return EnvSpec(observation_shape=obs.shape, action_shape=action_shape)

    def playground_state(self, sim: PlaygroundSim) -> mjx_env.State:
        """Playground's state of `sim` (with any leading batch axes)."""
        return self.layout.unpack(sim.arrays)

    def default_params(self) -> PlaygroundParams:
        return PlaygroundParams(max_episode_steps=jnp.asarray(self.episode_length, jnp.int32))

    @contextlib.contextmanager
    def _physics(self, params: PlaygroundParams) -> Iterator[Any]:
        """The Playground env with its model scaled by `params` while the block traces a call to it."""
        self.playground._mjx_model = scaled_model(self._nominal_model, params)
        try:
            yield self.playground
        finally:
            self.playground._mjx_model = self._nominal_model

    def _reset(self, key: jax.Array, params: PlaygroundParams) -> tuple[PlaygroundSim, Observation, Any]:
        with self._physics(params) as playground:
            state = strongly_typed(playground.reset(key))
        sim = PlaygroundSim(arrays=self.layout.pack(state), steps=jnp.zeros((), jnp.int32))
        return sim, observation(state.obs, self.privileged), state.metrics

    def carried_over(self, ended: PlaygroundSim, fresh: PlaygroundSim) -> PlaygroundSim:
        """`fresh` with the `carry_info` keys of its Playground info taken from `ended`'s."""
        if not self.carry_info:
            return fresh
        started = self.playground_state(fresh)
        kept = {name: self.playground_state(ended).info[name] for name in self.carry_info}
        return PlaygroundSim(arrays=self.layout.pack(started.replace(info={**started.info, **kept})), steps=fresh.steps)

    def _transition(self, sim: PlaygroundSim, action: jax.Array, params: PlaygroundParams) -> Transition:
        # Playground's step updates its state's metrics and info dicts in place: it gets a state rebuilt from the
        # sim's arrays, so the state passed in stays as it was.
        with self._physics(params) as playground:
            state = strongly_typed(playground.step(self.playground_state(sim), action))
        steps = sim.steps + 1
        return Transition(
            sim=PlaygroundSim(arrays=self.layout.pack(state), steps=steps),
            obs=observation(state.obs, self.privileged),
            reward=state.reward,
            terminated=state.done > 0,
            success=self._success(state, steps >= params.max_episode_steps),
            info=state.metrics,
        )

    def _success(self, state: mjx_env.State, at_time_limit: jax.Array) -> jax.Array:
        """[] bool: the task's own success metric, else its criterion at the time limit (`END_CRITERIA`), else
        False."""
        for name in SUCCESS_METRICS:
            if name in state.metrics:
                return state.metrics[name] > 0
        if self._end_criterion is not None:
            return self._end_criterion(state) & at_time_limit & (state.done == 0)
        return jnp.zeros((), jnp.bool_)

    def render(self, state, params: PlaygroundParams) -> np.ndarray:
        """One (non-batched) state drawn by Playground's renderer from its default camera, uint8 [240, 320, 3]."""
        return np.asarray(mjx_env.render_array(self.mj_model, self.playground_state(state.sim), height=240, width=320))
