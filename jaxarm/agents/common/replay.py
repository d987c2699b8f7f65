"""A uniform replay buffer that lives on device inside the compiled training loop.

Pure `init / add / sample` over a `ReplayState` pytree: a circular buffer of any pytree of items with an
insert position and a size. Written here rather than taken from a library (flashbax) because it is a
few lines, adds no dependency, stores exactly what the learner asks for, and as a plain pytree of arrays
it is checkpointed with the rest of the learner state and vmapped over seeds × hyper-parameters.

It must stay free of learner logic: what an item holds (obs, action, reward, the pre-reset next obs,
`terminated`) is the learner's choice.
"""

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class ReplayState:
    """A circular buffer.

    Attributes:
      items: pytree of arrays, every leaf [capacity, ...].
      position: [] int32, where the next item is written.
      size: [] int32, items stored so far (at most capacity).
    """

    items: Any
    position: jax.Array
    size: jax.Array

    @property
    def capacity(self) -> int:
        return jax.tree.leaves(self.items)[0].shape[0]


def init(example_item, capacity: int) -> ReplayState:
    """An empty buffer of `capacity` items shaped like `example_item` (a pytree of arrays, no batch axis)."""
    items = jax.tree.map(lambda leaf: jnp.zeros((capacity, *jnp.shape(leaf)), jnp.asarray(leaf).dtype), example_item)
    return ReplayState(items=items, position=jnp.zeros((), jnp.int32), size=jnp.zeros((), jnp.int32))


def add(state: ReplayState, batch) -> ReplayState:
    """Writes a batch of items (every leaf [N, ...], N <= capacity) at the insert position, wrapping around."""
    count = jax.tree.leaves(batch)[0].shape[0]
    if count > state.capacity:
        raise ValueError(f"cannot add {count} items to a replay buffer of capacity {state.capacity}")
    indices = (state.position + jnp.arange(count)) % state.capacity
    items = jax.tree.map(lambda stored, new: stored.at[indices].set(new.astype(stored.dtype)), state.items, batch)
    return ReplayState(
        items=items,
        position=(state.position + count) % state.capacity,
        size=jnp.minimum(state.size + count, state.capacity),
    )


def sample(state: ReplayState, key: jax.Array, batch_size: int):
    """`batch_size` items drawn uniformly with replacement from the stored ones; leaves [batch_size, ...].

    The buffer must hold at least one item.
    """
    indices = jax.random.randint(key, (batch_size,), 0, state.size)
    return jax.tree.map(lambda stored: stored[indices], state.items)
