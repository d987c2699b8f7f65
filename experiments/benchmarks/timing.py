"""Timing of jitted functions for the benchmark suites."""

import time

import jax
import numpy as np


def time_jitted(run, state, repeats: int) -> tuple[float, float]:
    """(compile + first call seconds, best of `repeats` call seconds) of a jitted `run(state) -> state`."""
    start = time.perf_counter()
    state = jax.block_until_ready(run(state))
    compile_seconds = time.perf_counter() - start
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        state = jax.block_until_ready(run(state))
        best = min(best, time.perf_counter() - start)
    return compile_seconds, best
