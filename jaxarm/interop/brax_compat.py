"""Restores the JAX API that brax 0.14.2's trainers still call, for jax >= 0.10 where it was removed.

brax's PPO, SAC and APG trainers (and `brax.training.pmap.bcast_local_devices`) replicate their training
state with `jax.device_put_replicated(tree, devices)`, which jax 0.10 removed. `install_device_put_replicated()`
puts back a function with the same contract, built on `jax.device_put` with a sharding: every leaf gains a
leading [len(devices)] axis, one identical slice per device, laid out exactly as brax's pmapped training epoch
lays out its own outputs (a NamedSharding over a 1-D mesh of `devices` whose axis bears the pmap's axis name),
so the epoch compiles once: on a mesh axis of another name, the same layout is an equivalent but unequal
sharding, and brax compiled its epoch a second time for its own outputs (seen on arm2d and the sorter: 84 s of
the sorter's 235 s on an H100).

Nothing else brax's PPO and SAC trainers use is missing on jax 0.10.2: `jax.pmap` still exists (now built on
shard_map; brax reads its outputs with `addressable_shards`, which works), and `jax.tree_util.tree_map` is
still there. This module patches nothing when imported; `BraxEnv` (brax_env.py) installs the function when it
is constructed, so a brax trainer given one finds it. It never replaces a `jax.device_put_replicated` that jax
itself provides.
"""

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

BRAX_PMAP_AXIS = "i"
"""The axis name every brax 0.14 trainer pmaps over (`_PMAP_AXIS_NAME` in its PPO, SAC and APG)."""


def device_put_replicated(x, devices: Sequence[jax.Device]):
    """`x` (a pytree) with every leaf stacked [len(devices), ...] and slice i placed on `devices[i]`. The
    parameters are named as jax's own (jax < 0.10) were, so that the shim stands in for it exactly."""
    devices = list(devices)
    if not devices:
        raise ValueError("device_put_replicated needs a non-empty sequence of devices")
    sharding = NamedSharding(Mesh(np.array(devices), (BRAX_PMAP_AXIS,)), PartitionSpec(BRAX_PMAP_AXIS))

    def replicate(leaf):
        leaf = jnp.asarray(leaf)
        return jax.device_put(jnp.broadcast_to(leaf[None], (len(devices),) + leaf.shape), sharding)

    return jax.tree.map(replicate, x)


def install_device_put_replicated() -> bool:
    """Sets `jax.device_put_replicated` to `device_put_replicated` if jax lacks it; True if it installed it."""
    if hasattr(jax, "device_put_replicated"):
        return False
    jax.device_put_replicated = device_put_replicated
    return True
