"""arm2d env steps/s (auto-reset and episode statistics included) beside the numpy reference, same run.

The JAX env runs `steps` steps inside one jitted `lax.scan` per batch size; the peers are the plain-numpy
reference stepping one env in a Python loop (the classic tutorial's way) and the same numpy code on a batch.
"""

import argparse
import functools
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from experiments.benchmarks.arguments import count, env_counts
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import time_jitted
from jaxarm import envs
from jaxarm.envs.arm2d import GOAL_UNIFORM_REACHABLE
from jaxarm.envs.arm2d.numpy_reference import ClassicArm


def jax_steps_per_second(
    num_envs: int, steps: int, auto_reset: bool = True, unroll: int = 1, repeats: int = 3
) -> tuple[float, float]:
    """(env steps/s of the best repeat, compile seconds) for `num_envs` envs over `steps` steps.

    Without auto-reset, episodes that end keep stepping (the env's maths is the same): that column shows
    what the auto-reset costs. `unroll` steps share one loop iteration, so XLA can fuse them and keep the
    state in registers between them.
    """
    env = envs.make("arm2d")
    params = envs.override_params(env.default_params(), {"goal_mode": GOAL_UNIFORM_REACHABLE})
    batch = envs.VmapEnv(envs.AutoReset(env) if auto_reset else env, num_envs)
    # A fixed bang-bang action pattern: cheap to make, and it visits goals, resets and time limits.
    pattern = jnp.sign(jax.random.normal(jax.random.PRNGKey(1), (num_envs, env.spec.action_size)))

    @functools.partial(jax.jit, compiler_options=envs.compiler_options(env))
    def run(state):
        def body(carry, step):
            return batch.step(carry, pattern * jnp.cos(step * 0.05), params), None

        state, _ = jax.lax.scan(body, state, jnp.arange(steps, dtype=jnp.float32), unroll=unroll)
        return state

    state = jax.jit(batch.reset)(jax.random.PRNGKey(0), params)
    compile_seconds, best = time_jitted(run, state, repeats)
    return num_envs * steps / best, compile_seconds


def scan_length(num_envs: int, steps: int, max_env_steps: int) -> int:
    """Steps per timed scan: `steps`, fewer where `num_envs` x `steps` would pass `max_env_steps`, at least 10."""
    return max(10, min(steps, max_env_steps // num_envs))


def default_max_env_steps(backend: str) -> int:
    """Env steps one timed call may take: 2e7 on a CPU (seconds there); 2e9 on an accelerator, where a call
    must run long enough to hide its fixed dispatch cost (under the CPU's cap, 1M envs ran 19 steps, ~2 ms)."""
    return 2 * 10**7 if backend == "cpu" else 2 * 10**9


def numpy_steps_per_second(num_envs: int | None, seconds: float = 1.0) -> float:
    """Env steps/s of the numpy reference: one env in a Python loop (None) or a numpy batch of `num_envs`."""
    rng = np.random.default_rng(0)
    shape = () if num_envs is None else (num_envs,)
    arm = ClassicArm()
    arm.reset_to(rng.uniform(0, 2 * np.pi, shape + (2,)), rng.uniform(0, 400, shape + (2,)))
    actions = rng.uniform(-1, 1, (256,) + shape + (2,)).astype(np.float32)
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for action in actions:
            _, _, terminated, truncated = arm.step(action)
            if num_envs is None and (terminated or truncated):
                arm.reset_to(rng.uniform(0, 2 * np.pi, 2), rng.uniform(0, 400, 2))
        count += len(actions)
    return count * (1 if num_envs is None else num_envs) / (time.perf_counter() - start)


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench arm2d", description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=env_counts, default="1,1024,65536,1048576", help="comma-separated env counts")
    parser.add_argument("--steps", type=count, default=1000, help="steps per timed scan")
    parser.add_argument(
        "--max-env-steps",
        type=int,
        help="env steps per timed call, at most (default: 2e7 on a CPU, 2e9 on an accelerator)",
    )
    parser.add_argument(
        "--unroll", type=count, default=8, help="env steps per scan iteration (8 ran 1.4x faster than 1 on an H200)"
    )
    add_out_argument(parser)
    args = parser.parse_args(argv)
    max_env_steps = args.max_env_steps or default_max_env_steps(jax.default_backend())
    reference = numpy_steps_per_second(None)
    batched_numpy = numpy_steps_per_second(1024)
    device = jax.devices()[0].device_kind
    print(
        f"device: {device}; jax {jax.__version__}; scan unroll {args.unroll}; "
        f"at most {max_env_steps:,} env steps per timed call"
    )
    print(f"numpy reference, single env loop: {reference:,.0f} steps/s")
    print(f"numpy reference, batch of 1024:   {batched_numpy:,.0f} steps/s ({batched_numpy / reference:,.0f}x single)")
    print("| envs | env steps/s (auto-reset, statistics) | vs numpy single env | without auto-reset | compile s |")
    print("|---:|---:|---:|---:|---:|")
    rows = []
    for size in args.sizes:
        steps = scan_length(size, args.steps, max_env_steps)
        rate, compile_seconds = jax_steps_per_second(size, steps, unroll=args.unroll)
        bare, _ = jax_steps_per_second(size, steps, auto_reset=False, unroll=args.unroll)
        print(
            f"| {size:,} | {rate:,.3g} | {rate / reference:,.0f}x | {bare:,.3g} | {compile_seconds:.1f} |", flush=True
        )
        rows.append(
            {
                "envs": size,
                "steps_per_scan": steps,
                "env_steps_per_second": rate,
                "vs_numpy_single_env": rate / reference,
                "env_steps_per_second_without_auto_reset": bare,
                "compile_seconds": compile_seconds,
            }
        )
    write_record(
        args.out,
        "arm2d",
        argv,
        rows,
        unroll=args.unroll,
        max_env_steps=max_env_steps,
        numpy_single_env_steps_per_second=reference,
        numpy_batch_1024_steps_per_second=batched_numpy,
    )
