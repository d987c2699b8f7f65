"""A uniformly random permutation that XLA:CPU computes ~4x faster than `jax.random.permutation`.

`jax.random.permutation` sorts (random key, index) pairs over several rounds; XLA:CPU sorts such pairs ~5x
slower than one array (16,384 elements on the 2-core CPU: 3.6 ms against 0.68 ms), and PPO shuffles its
samples every epoch. Here each round packs the index into the low bits of one uint32 key, random bits above,
and sorts that single array (16,384 elements: 1.55 ms against 6.36 ms for `jax.random.permutation`). Equal
random bits keep the order the previous round gave, so, as in `jax.random.permutation`, there are enough
rounds that an equal draw in every round is negligible (n^3 / 2^(random bits x rounds) ≤ 1).
"""

import math

import jax
import jax.numpy as jnp

MAX_PACKED_INDEX_BITS = 24
"""Up to 2^24 elements the key keeps ≥ 8 random bits; larger sizes use `jax.random.permutation`."""


def index_bits(n: int) -> int:
    """Low bits of each 32-bit key that hold an index below `n`."""
    return max(1, (n - 1).bit_length())


def rounds_needed(n: int) -> int:
    """Sorting rounds for `n` elements, the index in the low bits of each 32-bit key."""
    return max(1, math.ceil(3 * index_bits(n) / (32 - index_bits(n))))


def random_permutation(key: jax.Array, n: int) -> jax.Array:
    """[n] int32: a uniformly random permutation of 0 … n−1 (`n` static)."""
    if index_bits(n) > MAX_PACKED_INDEX_BITS:
        return jax.random.permutation(key, n)
    positions = jnp.arange(n, dtype=jnp.uint32)
    index_mask = jnp.uint32((1 << index_bits(n)) - 1)
    order = positions
    for round_key in jax.random.split(key, rounds_needed(n)):
        packed = (jax.random.bits(round_key, (n,), jnp.uint32) & ~index_mask) | positions
        order = order[jnp.sort(packed) & index_mask]
    return order.astype(jnp.int32)
