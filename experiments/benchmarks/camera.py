"""Envs that see, beside the same env observing state, in one run: env steps/s and camera images/s.

Each pair is one registered env with `obs_mode` "state" and "pixels+proprio" (arm2d: its JAX rasteriser; the
Panda envs: the analytic ray caster of `jaxarm/envs/panda/camera.py`, every camera of the env), stepped as
auto-reset batches under random actions in one jitted scan per batch size (`panda_sort.env_rates`).
`--train-configs` also compiles one update of each named preset's learner, as the runner compiles a chunk, and
reports the seconds to trace and compile it: a pixel learner's program holds the caster at every place it draws.
"""

import argparse
from collections.abc import Sequence

import jax

from experiments import configs
from experiments.benchmarks.arguments import count, env_counts
from experiments.benchmarks.panda_sort import env_rates
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import compile_updates
from jaxarm import envs
from jaxarm.agents.common.config import apply_overrides


def cameras_of(env) -> int:
    """Images per observation: the Panda envs' cameras, arm2d's one."""
    return len(getattr(env, "cameras", ())) or 1


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench camera", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--envs", default="arm2d,peg_insert", help="comma-separated registered envs with obs_mode ('': none)"
    )
    parser.add_argument(
        "--sizes",
        type=env_counts,
        default="1,16",
        help="comma-separated env counts (e.g. 1,1024,4096 on a GPU; 1-16 on a CPU)",
    )
    parser.add_argument("--resolution", type=count, default=64, help="side of the camera images, pixels")
    parser.add_argument("--steps", type=count, default=20, help="env steps per timed scan")
    parser.add_argument("--repeats", type=count, default=2, help="timed repeats; the best is reported")
    parser.add_argument(
        "--train-configs",
        default="",
        help="comma-separated presets whose update is compiled, at their own resolution (e.g. ppo_peg_pixels)",
    )
    parser.add_argument("overrides", nargs="*", help="overrides key=value of the --train-configs presets")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    try:
        train_configs = {
            name: apply_overrides(configs.get(name), args.overrides) for name in args.train_configs.split(",") if name
        }
    except ValueError as error:
        parser.error(str(error))
    print(f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; {args.resolution}x{args.resolution} images")
    print("| env | envs | state env steps/s | pixel env steps/s | pixels / state | images/s | compile s (pixels) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    rows = []
    for name in filter(None, args.envs.split(",")):
        state_env = envs.make(name)
        pixel_env = envs.make(name, obs_mode="pixels+proprio", resolution=args.resolution)
        for size in args.sizes:
            state_rate, _ = env_rates(state_env, size, args.steps, args.repeats)
            pixel_rate, pixel_compile = env_rates(pixel_env, size, args.steps, args.repeats)
            images = pixel_rate * cameras_of(pixel_env)
            print(
                f"| {name} | {size:,} | {state_rate:,.4g} | {pixel_rate:,.4g} | {pixel_rate / state_rate:.2f} "
                f"| {images:,.4g} | {pixel_compile:.1f} |",
                flush=True,
            )
            rows.append(
                {
                    "env": name,
                    "envs": size,
                    "state_env_steps_per_second": state_rate,
                    "pixel_env_steps_per_second": pixel_rate,
                    "pixels_over_state": pixel_rate / state_rate,
                    "images_per_second": images,
                    "compile_seconds_pixels": pixel_compile,
                }
            )
    compile_seconds = {}
    if train_configs:
        print(f"\n| preset {' '.join(args.overrides)} | compile s (one update) |\n|---|---:|")
    for name, config in train_configs.items():
        compile_seconds[name] = compile_updates(config, num_updates=1)[3]
        print(f"| {name} | {compile_seconds[name]:.1f} |", flush=True)
    write_record(
        args.out,
        "camera",
        argv,
        rows,
        resolution=args.resolution,
        overrides=args.overrides,
        update_compile_seconds=compile_seconds,
    )
