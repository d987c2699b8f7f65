"""Test-wide set-up: JAX's persistent compilation cache, then jaxarm's XLA settings, before any test starts JAX.

MJX programs take one to three minutes each to compile on a 2-core CPU, and the same program is compiled in
several processes of one session (both xdist workers, the runner's subprocesses, the notebooks' kernels). They
all share one on-disk cache in `.jax-cache/` (git-ignored): a program compiled once is read back everywhere
after, and a second session on the same checkout compiles almost nothing. The variables are set in the
environment, not only in this process's config, so that child processes inherit them.
"""

import os
import pathlib

CACHE_DIR = pathlib.Path(__file__).resolve().parents[1] / ".jax-cache"

os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(CACHE_DIR))
# Programs that compile faster than this are not worth a disk write and a read.
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")

import jaxarm  # noqa: E402, F401  (applies jaxarm's XLA settings)
