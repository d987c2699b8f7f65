"""Runs of several processes (`jax.distributed`): who writes the run directory, and the decisions all must share.

Every process runs the same compiled programs on its own devices and holds the same replicated learner state,
so every process reaches each chunk end together. Process 0, the primary, alone writes the run directory (its
lock, config, metrics, evaluations; orbax writes checkpoints from all of them, each its own shards); the others
only read it. Decisions taken on the host between chunks (stop on Ctrl-C, on the time limit) are agreed, so that
no process waits forever for another in a collective. With one process all of this reduces to plain values.
"""

import jax
import numpy as np
from jax.experimental import multihost_utils


def is_primary() -> bool:
    """Whether this process writes the run directory (process 0, or the only one)."""
    return jax.process_index() == 0


def any_process(flag: bool) -> bool:
    """Whether `flag` holds in any process (every process must call this at the same point)."""
    if jax.process_count() == 1:
        return flag
    return bool(np.any(multihost_utils.process_allgather(np.asarray(flag))))


def wait_for_all(name: str) -> None:
    """Returns once every process has reached the barrier `name` (at once with one process)."""
    if jax.process_count() > 1:
        multihost_utils.sync_global_devices(name)
