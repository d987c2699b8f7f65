"""Test-wide set-up: JAX's persistent compilation cache, then jaxarm's XLA settings, before any test starts JAX.

MJX programs take one to three minutes each to compile on a 2-core CPU, and the same program is compiled in
several processes of one session (both xdist workers, the runner's subprocesses, the notebooks' kernels). They
all share the on-disk cache the commands use (run, eval, sweep, bench: `jaxarm.runner.cache.cache_dir()`,
`~/.cache/jaxarm/jax` by default): a program compiled once is read back everywhere after, by the tests and the
commands alike. `JAXARM_COMPILATION_CACHE` moves it or turns it off here too. The variables are set in the
environment, not only in this process's config, so that child processes inherit them.
"""

import os

from jaxarm.runner import cache  # imports jaxarm, whose XLA settings apply before JAX starts its backend

CACHE_DIR = cache.enable_compilation_cache()
"""The cache of this process; None where JAX_COMPILATION_CACHE_DIR is set (JAX's own wins) or it is turned off."""

if CACHE_DIR is not None:  # child processes: subprocess runs, notebook kernels
    os.environ["JAX_COMPILATION_CACHE_DIR"] = str(CACHE_DIR)
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", str(cache.MIN_COMPILE_SECONDS))
