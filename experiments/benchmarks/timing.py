"""Timing of jitted functions for the benchmark suites."""

import contextlib
import functools
import time
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from experiments import configs
from jaxarm import envs
from jaxarm.agents import registry as agents_registry
from jaxarm.agents.common.config import RunConfig
from jaxarm.agents.common.sharding import data_mesh, envs_split_over, state_shardings
from jaxarm.agents.common.teachers import learner_as_teacher
from jaxarm.agents.common.trainer import run_updates
from jaxarm.runner import learners
from jaxarm.runner.teacher import teacher_config as preset_teacher_config
from jaxarm.runner.teacher import teacher_preset


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


def timed(function, *args) -> float:
    """Seconds of one call of an already compiled `function`, results waited for."""
    start = time.perf_counter()
    jax.block_until_ready(function(*args))
    return time.perf_counter() - start


ACTION_POOL_SIZE = 16
"""Distinct action sets `env_seconds` cycles through."""


def benchmark_trainer(config: RunConfig):
    """`config`'s trainer; a teacher named by preset (`teacher=preset:NAME`) is that preset's policy untrained, so
    that a distilled student's program compiles and runs as in its run, with no teacher trained first."""
    if not teacher_preset(config):
        return learners.make_trainer(config)
    teacher_config = preset_teacher_config(config, configs.get)
    teacher = agents_registry.make_trainer(teacher_config)
    key, hparams = jax.random.PRNGKey(teacher_config.seed), teacher_config.hparams()
    state = jax.jit(teacher.init)(key, hparams)
    return agents_registry.make_trainer(config, teacher=learner_as_teacher(teacher, state))


def compile_updates(config: RunConfig, num_updates: int, devices: Sequence[jax.Device] | None = None):
    """(compiled program, initial state, hparams, compile seconds) of `num_updates` updates of `config`'s learner.

    One program compiled ahead of time as the runner compiles a chunk (with `Trainer.compiler_options`), but
    without donating its state, so that the same state can be run again and again. Given `devices`, the state is
    placed over them and each steps its share of the envs, as the runner does (`jaxarm.agents.common.sharding`);
    else everything runs on the default device.
    """
    trainer = benchmark_trainer(config)
    hparams = config.hparams()
    key = jax.random.PRNGKey(config.seed)
    mesh = None if devices is None else data_mesh(devices)
    with contextlib.nullcontext() if mesh is None else envs_split_over(mesh):
        shardings = None if mesh is None else state_shardings(jax.eval_shape(trainer.init, key, hparams), mesh)
        state = jax.jit(trainer.init, out_shardings=shardings)(key, hparams)
        start = time.perf_counter()
        program = jax.jit(
            functools.partial(run_updates, trainer, num_updates=num_updates),
            out_shardings=None if shardings is None else (shardings, None),
            compiler_options=trainer.compiler_options,
        )
        compiled = program.lower(state, hparams).compile()
    return compiled, state, hparams, time.perf_counter() - start


def env_seconds(
    config: RunConfig,
    num_envs: int,
    steps: int,
    compiler_options: dict | None = None,
    policy: Callable[[envs.Observation], jax.Array] | None = None,
) -> tuple[float, float]:
    """(best seconds of `steps` steps of `num_envs` auto-reset envs, compile seconds), `config`'s env and params.

    The envs step inside one `lax.scan`, compiled ahead of time with `compiler_options` (None: the env's own,
    `jaxarm.envs.compiler_options`, as our learners compile it), as a learner's rollout steps them, with
    actions drawn as an untrained policy draws them (tanh of a standard normal), from a pool of
    `ACTION_POOL_SIZE` sets drawn once, so that drawing them costs next to nothing; or, given `policy`
    (observations [num_envs, ...] -> actions [num_envs, A]), the actions it takes, so that the physics does
    what that policy makes it do (a trained policy grasps and carries: more contacts than random actions).
    """
    env, params = config.make_env()
    batch = envs.VmapEnv(envs.AutoReset(env), num_envs)
    pool = jnp.tanh(jax.random.normal(jax.random.PRNGKey(1), (ACTION_POOL_SIZE, num_envs, env.spec.action_size)))

    def run(state):
        def body(carry, index):
            action = pool[index] if policy is None else policy(carry.obs)
            return batch.step(carry, action, params), None

        return jax.lax.scan(body, state, jnp.arange(steps) % ACTION_POOL_SIZE)[0]

    state = jax.jit(batch.reset)(jax.random.PRNGKey(0), params)
    start = time.perf_counter()
    if compiler_options is None:
        compiler_options = envs.compiler_options(env)
    compiled = jax.jit(run, compiler_options=compiler_options).lower(state).compile()
    compile_seconds = time.perf_counter() - start
    timed(compiled, state)  # warm-up: first-call allocations
    return min(timed(compiled, state) for _ in range(2)), compile_seconds
