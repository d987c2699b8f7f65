"""Jitted programs of the registered envs, built once per test process and shared by every test file.

MJX programs take a minute or more each to compile on a 2-core CPU. The contract test, the Panda envs' own
tests and their variants all reset and step the same envs: through `compiled(name)` each program is traced and
compiled once per process (the persistent cache in tests/conftest.py shares it between processes), and the
tests that use one env are kept in one xdist worker with `xdist_group(name)` (scripts/test.sh runs pytest with
`--dist loadgroup`).
"""

import dataclasses
import functools
from collections.abc import Callable

import jax
import pytest

from jaxarm import envs


@dataclasses.dataclass(frozen=True)
class CompiledEnv:
    """A registered env with its default params and its jitted entry points.

    Attributes:
      env: the env, as `envs.make(name)` builds it.
      params: its default params.
      reset: jit(env.reset): (key, params) -> EnvState.
      step: jit(env.step): (state, action [A], params) -> EnvState.
      batched_reset: jit(vmap(env.reset)) over keys [B] with shared params -> EnvState [B].
    """

    env: envs.Env
    params: object
    reset: Callable
    step: Callable
    batched_reset: Callable


@functools.cache
def compiled(name: str) -> CompiledEnv:
    """The registered env `name` with its jitted programs (each compiles on its first call)."""
    env = envs.make(name)
    return CompiledEnv(
        env=env,
        params=env.default_params(),
        reset=jax.jit(env.reset),
        step=jax.jit(env.step),
        batched_reset=jax.jit(jax.vmap(env.reset, in_axes=(0, None))),
    )


def same_worker(name: str):
    """The xdist mark that keeps every test of env `name` in one worker, with its compiled programs."""
    return pytest.mark.xdist_group(name)
