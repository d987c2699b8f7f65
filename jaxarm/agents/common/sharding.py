"""Data-parallel placement of a learner state over devices with `jax.sharding` (not pmap).

The env batch (every leaf of `state.env_state`, leading axis [num_envs]) is split across a 1-D mesh named
"data"; everything else (parameters, optimizer state, normaliser, replay, key) is replicated. The same
jitted update then runs SPMD: XLA partitions the rollout across devices and inserts the all-reduces
that average gradients, so results match a single device up to float summation order.
"""

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec


def data_mesh(devices=None) -> Mesh:
    """A 1-D mesh named "data" over `devices` (default: all devices of all processes)."""
    return Mesh(np.array(jax.devices() if devices is None else devices), ("data",))


def data_parallel(state, mesh: Mesh):
    """Places `state` on `mesh`: `state.env_state` split along axis 0, all other leaves replicated.

    Raises ValueError when the env batch does not divide by the number of devices.
    """
    count = mesh.devices.size
    num_envs = jax.tree.leaves(state.env_state)[0].shape[0]
    if num_envs % count:
        raise ValueError(f"num_envs={num_envs} must divide by the {count} devices it is split over")
    replicated = jax.device_put(state.replace(env_state=None), NamedSharding(mesh, PartitionSpec()))
    split = jax.device_put(state.env_state, NamedSharding(mesh, PartitionSpec("data")))
    return replicated.replace(env_state=split)
