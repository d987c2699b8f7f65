"""Panda sorter (MJX) env steps/s and physics steps/s beside bare jit(vmap(mjx.step)) of the same model, same run.

`--impl jax,warp` times both MJX implementations in one run (Warp needs warp-lang and a CUDA GPU).

The env runs `steps` auto-reset env steps (random actions, IK, substeps, scoring, observation, statistics)
inside one jitted `lax.scan` per batch size. The peer steps the same mjx.Model (this episode's object sizes,
shared by all envs) with nothing but `mjx.step`, `steps x substeps` times in one scan; their ratio is the cost
of the env layer around the physics.
"""

import argparse
from collections.abc import Sequence

import jax
from mujoco import mjx

from experiments.benchmarks.arguments import count, env_counts
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import time_jitted
from jaxarm import envs


def env_rates(env, num_envs: int, steps: int, repeats: int) -> tuple[float, float]:
    """(env steps/s, compile seconds) of `num_envs` auto-reset envs over `steps` random-action steps."""
    params = env.default_params()
    batch = envs.VmapEnv(envs.AutoReset(env), num_envs)

    @jax.jit
    def run(state):
        def body(carry, step_key):
            action = jax.random.uniform(step_key, (num_envs, *env.spec.action_shape), minval=-1.0, maxval=1.0)
            return batch.step(carry, action, params), None

        return jax.lax.scan(body, state, jax.random.split(jax.random.key(1), steps))[0]

    state = jax.jit(batch.reset)(jax.random.key(0), params)
    compile_seconds, best = time_jitted(run, state, repeats)
    return num_envs * steps / best, compile_seconds


def bare_mjx_rates(env, num_envs: int, physics_steps: int, repeats: int) -> tuple[float, float]:
    """(physics steps/s, compile seconds) of jit(vmap(mjx.step)) on the env's model, from reset states."""
    params = env.default_params()
    keys = jax.random.split(jax.random.key(0), num_envs)
    sims = jax.vmap(lambda key: env.reset(key, params).sim)(keys)
    model = env.episode_model(jax.tree.map(lambda leaf: leaf[0], sims), params)
    data = jax.jit(jax.vmap(lambda sim: env.kinematics(model, sim)))(sims)
    step = jax.vmap(lambda d: mjx.step(model, d))

    @jax.jit
    def run(state):
        return jax.lax.scan(lambda carry, _: (step(carry), None), state, None, length=physics_steps)[0]

    compile_seconds, best = time_jitted(run, data, repeats)
    return num_envs * physics_steps / best, compile_seconds


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench panda_sort", description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="panda_sort", help="registered panda_sort variant")
    parser.add_argument(
        "--sizes",
        type=env_counts,
        default="1,64",
        help="comma-separated env counts (e.g. 1,1024,4096,16384 on a GPU; at most 64 on a CPU)",
    )
    parser.add_argument("--impl", default="jax", help='comma-separated MJX implementations: "jax", "warp"')
    parser.add_argument("--steps", type=count, default=20, help="env steps per timed scan")
    parser.add_argument("--repeats", type=count, default=2, help="timed repeats; the best is reported")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    sizes = args.sizes
    # Warp's contact buffer is shared by a batch: sized for the largest.
    env_by_impl = {impl: envs.make(args.env, impl=impl, max_envs=max(sizes)) for impl in args.impl.split(",")}
    env = next(iter(env_by_impl.values()))
    print(
        f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; env {args.env}: "
        f"{env.objects_count} objects, {env.substeps} physics substeps per env step, "
        f"{env.mj_model.npair} contact pairs"
    )
    print(
        "| impl | envs | env steps/s | physics steps/s (env) | bare mjx.step physics steps/s | env / bare "
        "| compile s (env) | compile s (bare) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    rows = []
    for impl, env in env_by_impl.items():
        for size in sizes:
            rate, env_compile = env_rates(env, size, args.steps, args.repeats)
            bare, bare_compile = bare_mjx_rates(env, size, args.steps * env.substeps, args.repeats)
            physics = rate * env.substeps
            print(
                f"| {impl} | {size:,} | {rate:,.4g} | {physics:,.4g} | {bare:,.4g} | {physics / bare:.2f} "
                f"| {env_compile:.1f} | {bare_compile:.1f} |",
                flush=True,
            )
            rows.append(
                {
                    "impl": impl,
                    "envs": size,
                    "env_steps_per_second": rate,
                    "physics_steps_per_second": physics,
                    "bare_mjx_physics_steps_per_second": bare,
                    "env_over_bare": physics / bare,
                    "compile_seconds_env": env_compile,
                    "compile_seconds_bare": bare_compile,
                }
            )
    write_record(
        args.out,
        "panda_sort",
        argv,
        rows,
        env=args.env,
        objects=env.objects_count,
        substeps=env.substeps,
        contact_pairs=env.mj_model.npair,
    )
