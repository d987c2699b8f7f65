"""Data-parallel placement of a learner state over devices with `jax.sharding` (not pmap), in one process or many.

The env batch (every leaf of `state.env_state`, leading axis [num_envs]) is split across a 1-D mesh over
every device of every process, named ENV_AXIS; everything else (parameters, optimizer state, normaliser,
replay, key) is replicated. The same jitted update then runs SPMD: traced under `envs_split_over(mesh)`,
`VmapEnv` steps each device's share of the envs on that device alone (`jaxarm.envs.wrappers.over_env_batch`),
and XLA inserts the all-reduces that average gradients, so results match a single device up to float summation
order. `num_envs` is the whole batch, over all devices: a config computes the same run on any number of them.
A sweep's independent runs (seeds × values) are shared out whole instead, each device running its own
(`over_members`).
"""

from collections.abc import Callable

import jax
import numpy as np
from jax.experimental import multihost_utils
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxarm.envs.wrappers import ENV_AXIS, envs_split_over

__all__ = [
    "data_mesh",
    "data_parallel",
    "envs_split_over",
    "gathered",
    "members_mesh",
    "over_members",
    "state_shardings",
]


def data_mesh(devices=None) -> Mesh:
    """A 1-D mesh named ENV_AXIS over `devices` (default: all devices of all processes).

    A mesh of several devices also switches this process's partitioner to GSPMD: with Shardy, JAX's default,
    XLA:GPU (jaxlib 0.11.2, H100) crashed compiling the sorter's update with its envs split by device, both MJX
    implementations (a segfault in backend_compile); under GSPMD it compiles and ppo_sorter steps 1.93x one
    GPU's env steps/s on 2 GPUs. Programs of one device are not partitioned, so nothing else changes.
    """
    chosen = jax.devices() if devices is None else list(devices)
    if len(chosen) > 1:
        jax.config.update("jax_use_shardy_partitioner", False)
    return Mesh(np.array(chosen), (ENV_AXIS,))


def members_mesh(members: int) -> Mesh | None:
    """A mesh over as many devices (of all processes) as evenly share `members` independent runs (a sweep's
    seeds × values), the most that divide their count; None where that is one device."""
    devices = jax.devices()
    count = max(size for size in range(1, len(devices) + 1) if members % size == 0)
    return data_mesh(devices[:count]) if count > 1 else None


def over_members(fn: Callable, mesh: Mesh | None) -> Callable:
    """`fn`, whose arguments and outputs all have a leading [members] axis, run on each device of `mesh` for its
    share of the members (each member computed as on one device); `fn` itself where `mesh` is None."""
    if mesh is None:
        return fn
    split = PartitionSpec(ENV_AXIS)
    # check_vma off, as in over_env_batch: MJX Warp's FFI outputs drop the varying-axis type.
    return jax.shard_map(fn, mesh=mesh, in_specs=split, out_specs=split, check_vma=False)


def gathered(tree):
    """`tree` (arrays that may span devices of other processes) as numpy arrays whole, on every process."""
    if jax.process_count() == 1:
        return jax.device_get(tree)
    return multihost_utils.process_allgather(tree, tiled=True)


def state_shardings(state, mesh: Mesh):
    """The shardings of `state` (a learner state, or its `jax.eval_shape`) on `mesh`: `state.env_state` split
    along axis 0, all other leaves replicated. Raises ValueError when the env batch does not divide by the
    number of devices."""
    count = mesh.devices.size
    num_envs = jax.tree.leaves(state.env_state)[0].shape[0]
    if num_envs % count:
        raise ValueError(f"num_envs={num_envs} must divide by the {count} devices it is split over")
    replicated, split = NamedSharding(mesh, PartitionSpec()), NamedSharding(mesh, PartitionSpec(ENV_AXIS))
    return jax.tree.map(lambda _: replicated, state).replace(env_state=jax.tree.map(lambda _: split, state.env_state))


def data_parallel(state, mesh: Mesh):
    """Places `state` on `mesh` (`state_shardings`). With several processes each passes the same `state` (the
    same seed, or the same checkpoint) and keeps its devices' shards."""
    return jax.device_put(state, state_shardings(state, mesh))
