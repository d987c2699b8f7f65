"""Scale-out over devices: PPO env steps/s of presets on 1, 2, 4 ... devices, and their time to a success rate.

Weak scaling, as a user scales out: each device keeps the preset's env count (`--envs-per-device` to change it),
so the run on D devices steps D times the envs, with Warp's buffers still sized for one device's share. For every
preset (default: `ppo_sorter`), MJX implementation (default: `auto`, Warp on an NVIDIA GPU, and `jax`) and device
count, the
steady rate of whole PPO updates (rollout, GAE, epochs × minibatches) is timed in one program compiled ahead of
time over the first D devices, as the runner compiles a chunk, compile excluded; the ratios are against one
device in the same call. With `--train-to SUCCESS`, each preset also trains (`jaxarm.runner.train`) on each count
in `--train-devices`, evaluating every `--eval-every` updates, and reports the wall clock from the training's
start (compilation included) to the first evaluation at that success rate.
"""

import argparse
import dataclasses
import pathlib
import shutil
import tempfile
import time
from collections.abc import Sequence

import jax

from experiments import configs, start_up
from experiments.benchmarks import arguments
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.scaling import ppo_seconds
from jaxarm import runner
from jaxarm.agents.common.config import RunConfig


def parse_counts(text: str) -> list[int]:
    return sorted({int(part) for part in text.split(",") if part})


def scaled_config(preset: str, devices: int, envs_per_device: int | None, impl: str | None = None) -> RunConfig:
    """`preset` with `envs_per_device` envs (default: the preset's) on each of `devices` devices; Warp's buffers
    (`max_envs`, where the preset sets it) hold one device's share; `impl`, where given, the MJX implementation."""
    config = configs.get(preset)
    per_device = envs_per_device or config.num_envs
    kwargs = dict(config.env_kwargs)
    if "max_envs" in kwargs:
        kwargs["max_envs"] = per_device
    if impl is not None:
        kwargs["impl"] = impl
    return dataclasses.replace(config, num_envs=per_device * devices, env_kwargs=tuple(kwargs.items()))


def variants(presets: Sequence[str], impls: Sequence[str]) -> list[tuple[str, str, str | None]]:
    """(label, preset, impl) for every preset, once per implementation in `impls` where it runs on MJX (its
    env_kwargs name an `impl`), once otherwise."""
    return [
        (f"{name} impl={impl}" if impl else name, name, impl)
        for name in presets
        for impl in (impls if "impl" in dict(configs.get(name).env_kwargs) else [None])
    ]


def steady_rate(config: RunConfig, devices: Sequence[jax.Device], updates: int) -> tuple[float, float]:
    """(env steps/s of `updates` updates on `devices`, compile seconds), best of two timed calls."""
    seconds, compile_seconds = ppo_seconds(config, config.num_envs, updates, devices)
    return updates * config.env_steps_per_update / seconds, compile_seconds


def time_to_success(
    config: RunConfig, devices: Sequence[jax.Device], target: float, eval_every: int, minutes: float
) -> dict:
    """Trains `config` on `devices` for at most `minutes` (a temporary run directory), evaluating every
    `eval_every` updates; the first evaluation at `target` success or better: its wall seconds (from the
    training's start, compilation included) and env steps, or None for both if none got there."""
    config = dataclasses.replace(config, eval_every_updates=eval_every)
    with tempfile.TemporaryDirectory() as name, start_up.CleanedOnCtrlC(lambda: shutil.rmtree(name, True)):
        folder = pathlib.Path(name)
        start = time.perf_counter()
        final = runner.train(config, folder, options=runner.Options(stop_after_s=60 * minutes, devices=devices))
        total = time.perf_counter() - start
        evaluations = [row for row in runner.read_metrics(folder) if "eval/success_rate" in row]
    reached = next((row for row in evaluations if row["eval/success_rate"] >= target), None)
    return {
        "seconds_to_target": None if reached is None else reached["wall_time"],
        "env_steps_to_target": None if reached is None else reached["env_steps"],
        "best_success": max((row["eval/success_rate"] for row in evaluations), default=None),
        "final_success": final["success_rate"],
        "train_seconds": total,
    }


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench devices", description=__doc__.splitlines()[0])
    parser.add_argument("--configs", default="ppo_sorter", help="PPO presets, comma-separated")
    parser.add_argument("--impls", default="auto,jax", help="MJX implementations of MJX presets, comma-separated")
    parser.add_argument("--devices", default="1,2,4", help="device counts; those beyond the host's are skipped")
    parser.add_argument("--envs-per-device", type=int, help="envs on each device (default: the preset's num_envs)")
    parser.add_argument("--updates", type=arguments.count, default=10, help="PPO updates per timed call")
    parser.add_argument("--train-to", type=float, help="also time training to this success rate (e.g. 0.9)")
    parser.add_argument("--train-devices", default="", help="device counts to train on (default: the largest)")
    parser.add_argument("--eval-every", type=int, default=20, help="updates between evaluations while training")
    parser.add_argument("--train-minutes", type=float, default=5.0, help="longest training per preset and count")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    available = jax.devices()
    counts = [count for count in parse_counts(args.devices) if count <= len(available)]
    presets = [name for name in args.configs.split(",") if name]
    for name in presets:
        configs.get(name)  # an unknown preset fails before anything compiles
    device = available[0].device_kind
    print(f"device: {device} x {len(available)}; jax {jax.__version__}; device counts {counts}", flush=True)

    runs = variants(presets, [impl for impl in args.impls.split(",") if impl])
    rows: list[dict] = []
    for label, name, impl in runs:
        for count in counts:
            config = scaled_config(name, count, args.envs_per_device, impl)
            rate, compile_seconds = steady_rate(config, available[:count], args.updates)
            rows.append({"config": label, "devices": count, "envs": config.num_envs, "env_steps_per_second": rate})
            rows[-1]["compile_seconds"] = compile_seconds
            print(f"  {label} on {count}: {config.num_envs:,} envs, {rate:,.0f} env steps/s", flush=True)
    print(f"\n| preset | devices | envs | env steps/s | over 1 device | compile s |  ({device})")
    print("|---|---:|---:|---:|---:|---:|")
    for row in rows:
        single = next(other for other in rows if other["config"] == row["config"] and other["devices"] == counts[0])
        row["over_first"] = row["env_steps_per_second"] / single["env_steps_per_second"]
        print(
            f"| {row['config']} | {row['devices']} | {row['envs']:,} | {row['env_steps_per_second']:,.0f} | "
            f"{row['over_first']:.2f}x | {row['compile_seconds']:.1f} |"
        )

    trainings = []
    if args.train_to is not None:
        train_counts = parse_counts(args.train_devices) or counts[-1:]
        for label, name, impl in runs:
            for count in (count for count in train_counts if count <= len(available)):
                config = scaled_config(name, count, args.envs_per_device, impl)
                result = time_to_success(config, available[:count], args.train_to, args.eval_every, args.train_minutes)
                trainings.append({"config": label, "devices": count, "envs": config.num_envs, **result})
                print(f"  {label} on {count} to {args.train_to:.0%}: {trainings[-1]}", flush=True)
    write_record(args.out, "devices", argv, rows, trainings=trainings, device_count=len(available))
