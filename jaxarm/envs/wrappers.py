"""Wrappers that keep the env contract: auto-reset and vmap over a batch of envs.

Episode statistics are kept by `Env.step` itself (`state.episode`, `state.last_episode`), so every env,
wrapped or not, reports the same numbers.
"""

import contextlib
import contextvars
import functools
import warnings
from collections.abc import Callable, Iterator, Sequence

import jax
import jax.numpy as jnp
from jax.sharding import Mesh, PartitionSpec

from jaxarm.envs.base import Env, EnvSpec, EnvState
from jaxarm.envs.observation import IMAGE, with_image

ENV_AXIS = "data"
"""The mesh axis an env batch is split along (jaxarm.agents.common.sharding builds the mesh)."""
_SPLIT_OVER: contextvars.ContextVar[Mesh | None] = contextvars.ContextVar("envs_split_over", default=None)
STARTS_DRAWN_SHARE = 8
"""A batch of B auto-resetting envs draws its new episodes' first images in groups of B / this many envs,
gathered: as many groups as a step needs, none on a step where no episode starts."""


class Wrapper:
    """Forwards the contract to an inner env; subclasses override what they change.

    `Env`'s hooks are forwarded one by one below; anything else the inner env offers (counts, layouts, ids,
    `uses_mjx`, `render`) through `__getattr__`. tests/envs/test_contract.py runs every wrapper over a camera env.
    """

    def __init__(self, env):
        self.env = env

    def __getattr__(self, name: str):
        if "env" not in self.__dict__:  # not yet set (copying, unpickling): no attribute, as Python expects
            raise AttributeError(name)
        return getattr(self.env, name)

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

    @property
    def draws_images(self) -> bool:
        return self.env.draws_images

    def images(self, sim, params) -> jax.Array:
        return self.env.images(sim, params)

    def reset_without_images(self, key: jax.Array, params) -> EnvState:
        return self.env.reset_without_images(key, params)

    def carried_over(self, ended, fresh):
        return self.env.carried_over(ended, fresh)

    def checked(self, state: EnvState) -> EnvState:
        return self.env.checked(state)


class AutoReset(Wrapper):
    """Starts a new episode inside `step` whenever the last one ended.

    After a done step, `obs`, `sim` (with what `Env.carried_over` keeps of the last one's), `step_count` and
    `episode` belong to the new episode, while `reward`, `terminated`, `truncated`, `final_obs` (the observation
    the episode ended on), `last_episode` and `info` describe the step that ended it.
    """

    def step(self, state: EnvState, action: jax.Array, params) -> EnvState:
        state = self._step_leaving_start_images(state, action, params)
        if not self.env.draws_images:
            return state
        # For one env the branch is real: a start's images are drawn only when it starts. (Under a plain vmap
        # it becomes a select that draws them for every env; `batch_step` avoids that.)
        return jax.lax.cond(state.done, functools.partial(self._draw_start_images, params=params), lambda s: s, state)

    def batch_step(self, state: EnvState, action: jax.Array, params, params_axis: int | None) -> EnvState:
        """`step` over a batch (leading [B] axes; `params` batched along `params_axis`, or shared if None),
        drawing new episodes' first images only for the envs that start one."""
        step = jax.vmap(self._step_leaving_start_images, in_axes=(0, 0, params_axis))
        state = step(state, action, params)
        if not self.env.draws_images:
            return state
        num_envs = state.done.shape[0]
        group = max(1, num_envs // STARTS_DRAWN_SHARE)
        groups = -(-num_envs // group)
        # The envs that start, first, padded with num_envs (the gathers clip it, the scatter drops it).
        starting = jnp.nonzero(state.done, size=groups * group, fill_value=num_envs)[0].reshape(groups, group)
        draw = jax.vmap(self.env.images, in_axes=(0, params_axis))

        def draw_group(index: jax.Array, image: jax.Array) -> jax.Array:
            envs = starting[index]
            gather = functools.partial(jnp.take, indices=envs, axis=0, mode="clip")
            group_params = params if params_axis is None else jax.tree.map(gather, params)
            return image.at[envs].set(draw(jax.tree.map(gather, state.sim), group_params), mode="drop")

        # A loop over as many groups as there are starts: one traced copy of the camera, and no work for none.
        image = jax.lax.fori_loop(0, -(-jnp.sum(state.done) // group), draw_group, state.obs[IMAGE])
        return state.replace(obs=with_image(state.obs, image))

    def _step_leaving_start_images(self, state: EnvState, action: jax.Array, params) -> EnvState:
        """`step`, except that where an episode started, obs[IMAGE] is left zero (`draws_images`)."""
        stepped = self.env.step(state, action, params)
        # The reset is computed for every env (vmap turns a branch into a select), so it must be cheap: it
        # draws from the carried key, which only advances when an episode ends. Random numbers dominated
        # the cost of a step (threefry hashes), so no extra split happens here. Its scope names it in profiles
        # (`bench profile --phases`).
        with jax.named_scope("auto_reset"):
            fresh = self.env.reset_without_images(stepped.key, params)
        done = stepped.done

        def pick(new, old):
            return jnp.where(done, new, old)

        return stepped.replace(
            sim=jax.tree.map(pick, self.env.carried_over(stepped.sim, fresh.sim), stepped.sim),
            obs=jax.tree.map(pick, fresh.obs, stepped.obs),
            step_count=pick(fresh.step_count, stepped.step_count),
            episode=jax.tree.map(pick, fresh.episode, stepped.episode),
            key=pick(fresh.key, stepped.key),
        )

    def _draw_start_images(self, state: EnvState, params) -> EnvState:
        """`state` (one env, just reset) with its observation's images drawn."""
        return state.replace(obs=with_image(state.obs, self.env.images(state.sim, params)))


@contextlib.contextmanager
def envs_split_over(mesh: Mesh) -> Iterator[None]:
    """While active, batches of envs traced in this thread step each device's share on that device, over `mesh`'s
    ENV_AXIS (`over_env_batch`). Only tracing reads it: trace (first call) a jitted function inside it.

    jaxarm's own context rather than `jax.set_mesh`, which also places every array made under it on the whole
    mesh: with several processes, a constant MJX makes eagerly then spans devices of other processes, and no
    program may close over it."""
    token = _SPLIT_OVER.set(mesh)
    try:
        yield
    finally:
        _SPLIT_OVER.reset(token)


def over_env_batch(batched_fn: Callable, num_envs: int, batched_args: Sequence[bool]) -> Callable:
    """`batched_fn` (whose outputs all have a leading [num_envs] axis), run on each device's share of the batch
    when traced under `envs_split_over(mesh)` with several devices dividing `num_envs`; `batched_fn` itself
    otherwise. `batched_args[i]` says whether argument i has the leading [num_envs] axis (split) or is shared
    (replicated).

    Envs of a batch are independent, so each device steps its own without any communication. Left to XLA's
    partitioner, a foreign call inside the step (MJX Warp's FFI) cannot be split: it gathers the whole batch onto
    every device and runs it there (the Warp sorter scaled 1.29x on 2 GPUs and 1.49x on 4).
    """
    mesh = _SPLIT_OVER.get()
    if mesh is None:
        return batched_fn
    devices = mesh.shape[ENV_AXIS]
    if devices == 1 or num_envs % devices:
        return batched_fn
    in_specs = tuple(PartitionSpec(ENV_AXIS) if split else PartitionSpec() for split in batched_args)
    # check_vma off: MJX Warp's FFI outputs drop the varying-axis type its inputs carry, which a scan's carry
    # then refuses (google-deepmind/mujoco#3426).
    return jax.shard_map(batched_fn, mesh=mesh, in_specs=in_specs, out_specs=PartitionSpec(ENV_AXIS), check_vma=False)


class VmapEnv(Wrapper):
    """A batch of `num_envs` independent envs; states and actions gain a leading [num_envs] axis.

    Traced under `envs_split_over(mesh)`, each device steps and resets its share of the batch (`over_env_batch`);
    the results are those of one device.

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
                f"runtime has deadlocked on it (see docs/tutorials/panda.md); the run may hang",
                stacklevel=2,
            )

    def reset(self, key: jax.Array, params) -> EnvState:
        return self._each_env(self.env.reset)(jax.random.split(key, self.num_envs), params)

    def reset_without_images(self, key: jax.Array, params) -> EnvState:
        """`reset`, with every env's obs[IMAGE] left zero where the env `draws_images`."""
        return self._each_env(self.env.reset_without_images)(jax.random.split(key, self.num_envs), params)

    def images(self, sim, params) -> jax.Array:
        """uint8 [B, H, W, C]: each env's camera images (`Env.images`) of a batch of sims [B]."""
        return self._each_env(self.env.images)(sim, params)

    def checked(self, state: EnvState) -> EnvState:
        """`Env.checked` of a batch [B]: each device checks its share, as it steps it."""
        return over_env_batch(self.env.checked, self.num_envs, (True,))(state)

    def _each_env(self, fn: Callable) -> Callable:
        """`fn(per-env argument, params)` over the batch: the first argument with a leading [B] axis."""
        each = jax.vmap(fn, in_axes=(0, self.params_axis))
        return over_env_batch(each, self.num_envs, (True, self.params_axis == 0))

    def step(self, state: EnvState, action: jax.Array, params) -> EnvState:
        if isinstance(self.env, AutoReset):
            step = functools.partial(self.env.batch_step, params_axis=self.params_axis)
        else:
            step = jax.vmap(self.env.step, in_axes=(0, 0, self.params_axis))
        return over_env_batch(step, self.num_envs, (True, True, self.params_axis == 0))(state, action, params)
