"""The packed-key random permutation: a permutation, uniform, deterministic per key."""

import jax
import numpy as np
import pytest

from jaxarm.agents.common.permutation import random_permutation, rounds_needed


@pytest.mark.parametrize("n", [1, 2, 7, 1000, 16384])
def test_every_index_appears_once(n):
    order = np.asarray(random_permutation(jax.random.PRNGKey(n), n))
    assert order.dtype == np.int32
    np.testing.assert_array_equal(np.sort(order), np.arange(n))


def test_positions_are_uniform_and_keys_decide_them():
    draws = np.asarray(
        jax.jit(jax.vmap(lambda key: random_permutation(key, 10)))(jax.random.split(jax.random.PRNGKey(0), 20_000))
    )
    # Where element 0 lands and which element comes first: 10 equally likely outcomes each (chi-square, 9 dof,
    # 27.9 is the 0.001 tail).
    for counts in (np.bincount(np.argmax(draws == 0, axis=1), minlength=10), np.bincount(draws[:, 0], minlength=10)):
        expected = len(draws) / 10
        assert np.sum((counts - expected) ** 2 / expected) < 27.9
    np.testing.assert_array_equal(
        random_permutation(jax.random.PRNGKey(5), 100), random_permutation(jax.random.PRNGKey(5), 100)
    )
    assert not np.array_equal(
        random_permutation(jax.random.PRNGKey(5), 100), random_permutation(jax.random.PRNGKey(6), 100)
    )


def test_more_rounds_as_fewer_random_bits_remain():
    assert rounds_needed(10) == 1
    assert rounds_needed(16384) == 3
    assert rounds_needed(1 << 20) == 5
