"""Envs that see, beside the same env observing state, in one run: env steps/s and camera images/s.

Each pair is one registered env with `obs_mode` "state" and "pixels+proprio" (arm2d: its JAX rasteriser; the
Panda envs: the analytic ray caster of `jaxarm/envs/panda/camera.py`, every camera of the env), stepped as
auto-reset batches under random actions in one jitted scan per batch size (`panda_sort.env_rates`).
"""

import argparse
from collections.abc import Sequence

import jax

from experiments.benchmarks.panda_sort import env_rates
from experiments.benchmarks.record import add_out_argument, write_record
from jaxarm import envs


def cameras_of(env) -> int:
    """Images per observation: the Panda envs' cameras, arm2d's one."""
    return len(getattr(env, "cameras", ())) or 1


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench camera", description=__doc__.splitlines()[0])
    parser.add_argument("--envs", default="arm2d,peg_insert", help="comma-separated registered envs with obs_mode")
    parser.add_argument(
        "--sizes", default="1,16", help="comma-separated env counts (e.g. 1,1024,4096 on a GPU; 1-16 on a CPU)"
    )
    parser.add_argument("--resolution", type=int, default=64, help="side of the camera images, pixels")
    parser.add_argument("--steps", type=int, default=20, help="env steps per timed scan")
    parser.add_argument("--repeats", type=int, default=2, help="timed repeats; the best is reported")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    sizes = [int(text) for text in args.sizes.split(",")]
    print(f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; {args.resolution}x{args.resolution} images")
    print("| env | envs | state env steps/s | pixel env steps/s | pixels / state | images/s | compile s (pixels) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    rows = []
    for name in args.envs.split(","):
        state_env = envs.make(name)
        pixel_env = envs.make(name, obs_mode="pixels+proprio", resolution=args.resolution)
        for size in sizes:
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
    write_record(args.out, "camera", argv, rows, resolution=args.resolution)
