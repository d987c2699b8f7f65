"""Throughput against the number of parallel envs: env steps/s and PPO training env steps/s, plotted.

For every requested env that is registered (default: arm2d, panda_sort), with the params of its PPO preset:
- env steps/s of `num_envs` auto-reset envs stepping inside one jitted `lax.scan` (compile excluded);
- PPO env steps/s: whole updates (rollout, GAE, epochs × minibatches) of our PPO with the preset's
  hyper-parameters at `num_envs` envs, compiled ahead of time, compile excluded;
- where PPO's time goes at the preset's env count (when the sweep reached it): the whole update, the envs
  stepping alone under random actions, and the envs stepping under the untrained policy's actions (its
  network and normaliser run each step), so the differences isolate the policy side of the rollout and the
  learning (the normaliser's update, value passes, GAE and SGD).
Sizes are tried in increasing order; the previous size's rate shortens each timed call to fit
`--max-seconds`, and the sweep stops where even the shortest call would not fit (MJX envs on CPU stop
early; their compile times are minutes there). One device is used; the output and the plot's title say how
many there are (multi-device runs come later). The figure goes to `--plot`.
"""

import argparse
import dataclasses
import pathlib
from collections.abc import Callable, Sequence

import jax
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from experiments.benchmarks.arguments import env_counts
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import compile_updates, env_seconds, timed
from experiments.benchmarks.training import base_ppo_config
from jaxarm import envs
from jaxarm.agents.common.config import RunConfig, with_pair
from jaxarm.agents.ppo import PPOConfig, make_trainer


def safe_sizes(env_name: str, sizes: list[int]) -> list[int]:
    """`sizes` without those above the env's `cpu_max_envs` when running on a CPU (they can hang there)."""
    limit = envs.make(env_name).cpu_max_envs
    if limit is None or jax.default_backend() != "cpu":
        return sizes
    dropped = [size for size in sizes if size > limit]
    if dropped:
        print(
            f"  {env_name}: skipping {', '.join(f'{size:,}' for size in dropped)} envs on the CPU "
            f"(above {limit} the CPU runtime can deadlock on this env; see docs/tutorials/panda.md)",
            flush=True,
        )
    return [size for size in sizes if size <= limit]


def scaling_config(env_name: str, impl: str, max_envs: int) -> PPOConfig:
    """The PPO preset of `env_name`; for an MJX env with `impl` "warp", on Warp with buffers for `max_envs` envs."""
    config = base_ppo_config(env_name)
    if impl == "jax" or not envs.make(env_name).uses_mjx:
        return config
    kwargs = with_pair(with_pair(config.env_kwargs, "impl", impl), "max_envs", max_envs)
    return dataclasses.replace(config, env_kwargs=kwargs)


def ppo_seconds(
    base: RunConfig, num_envs: int, num_updates: int, devices: Sequence[jax.Device] | None = None
) -> tuple[float, float]:
    """(seconds of `num_updates` learner updates, best of two calls after a warm-up; compile seconds) of `base` at
    `num_envs` envs, split over `devices` (None: the default device alone)."""
    config = dataclasses.replace(base, num_envs=num_envs)
    compiled, state, hparams, compile_seconds = compile_updates(config, num_updates, devices)
    timed(compiled, state, hparams)  # warm-up
    seconds = min(timed(compiled, state, hparams) for _ in range(2))
    return seconds, compile_seconds


@dataclasses.dataclass(frozen=True)
class Measure:
    """One throughput measurement, repeated `units` times per timed call (scan steps or PPO updates).

    Attributes:
      run: (num_envs, units) -> (seconds of one timed call, compile seconds).
      steps_per_unit: num_envs -> env steps per unit.
      min_units, max_units: bounds on units per timed call.
    """

    run: Callable[[int, int], tuple[float, float]]
    steps_per_unit: Callable[[int], int]
    min_units: int
    max_units: int


def env_measure(config: PPOConfig) -> Measure:
    return Measure(lambda size, units: env_seconds(config, size, units), lambda size: size, 10, 1000)


def ppo_measure(config: PPOConfig) -> Measure:
    per_unit = config.rollout_length
    return Measure(lambda size, units: ppo_seconds(config, size, units), lambda size: size * per_unit, 1, 20)


def sweep(sizes: list[int], measure: Measure, target_steps: int, max_seconds: float) -> list[tuple[int, float, float]]:
    """[(size, env steps/s, compile s)]: about `target_steps` env steps per timed call, fewer for slow envs.

    The previous size's rate sizes each call to at most half of `max_seconds`; the sweep stops before a size
    whose smallest call (`min_units`) would still take longer than `max_seconds`.
    """
    rows: list[tuple[int, float, float]] = []
    for size in sizes:
        per_unit = measure.steps_per_unit(size)
        budget = target_steps if not rows else min(target_steps, rows[-1][1] * max_seconds / 2)
        if rows and measure.min_units * per_unit / rows[-1][1] > max_seconds:
            print(f"  skipping {size:,} envs and up: a timed call would take over {max_seconds:g} s", flush=True)
            break
        units = int(np.clip(budget // per_unit, measure.min_units, measure.max_units))
        seconds, compile_seconds = measure.run(size, units)
        rows.append((size, units * per_unit / seconds, compile_seconds))
        print(f"  {size:>7,} envs: {rows[-1][1]:>12,.0f} env steps/s (compile {compile_seconds:.1f} s)", flush=True)
    return rows


def time_breakdown(config: PPOConfig, num_updates: int) -> list[tuple[str, float]]:
    """[(phase, milliseconds per update)] of our PPO at the preset's env count (see the module docstring)."""
    full, _ = ppo_seconds(config, config.num_envs, num_updates)
    env_steps = config.rollout_length * num_updates
    env_only, _ = env_seconds(config, config.num_envs, env_steps)
    trainer = make_trainer(config)
    state = jax.jit(trainer.init)(jax.random.PRNGKey(config.seed), config.hparams())
    under_policy, _ = env_seconds(config, config.num_envs, env_steps, policy=lambda obs: trainer.act(state, obs))
    sgd_steps = config.num_epochs * config.num_minibatches
    per_update = 1000.0 / num_updates
    return [
        ("whole update", full * per_update),
        (f"env stepping alone ({config.num_envs:,} envs × {config.rollout_length} steps)", env_only * per_update),
        ("the policy's network and normaliser in the rollout", (under_policy - env_only) * per_update),
        (
            f"normaliser update, value passes, GAE and SGD: {config.num_epochs} epochs × {config.num_minibatches} "
            f"minibatches of {config.minibatch_size:,}",
            (full - under_policy) * per_update,
        ),
        ("  per SGD step, value passes and GAE included", (full - under_policy) * per_update / sgd_steps),
    ]


def plot(curves: dict[str, list[tuple[int, float, float]]], path: pathlib.Path, title: str) -> None:
    """Log-log env steps/s against num_envs, one line per (env, measurement)."""
    fig, ax = plt.subplots(figsize=(8, 5))
    for label, rows in curves.items():
        if rows:
            sizes, rates, _ = zip(*rows, strict=True)
            ax.plot(sizes, rates, marker="o", label=label)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("parallel envs")
    ax.set_ylabel("env steps / s (compile excluded)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench scaling", description=__doc__.splitlines()[0])
    parser.add_argument("--envs", default="arm2d,panda_sort", help="env names; unregistered ones are skipped")
    parser.add_argument(
        "--env-sizes", type=env_counts, default="1,16,256,1024,4096,16384,65536", help="env counts for env stepping"
    )
    parser.add_argument(
        "--ppo-sizes", type=env_counts, default="16,64,256,1024,4096,16384,65536", help="env counts for PPO"
    )
    parser.add_argument("--max-seconds", type=float, default=45.0, help="longest predicted timed call per size")
    parser.add_argument("--quick", action="store_true", help="CPU smoke run: fewer steps, calls under 5 s")
    parser.add_argument("--plot", default="benchmarks_scaling.png", help="where the PNG goes")
    parser.add_argument(
        "--impl", default="jax", help='MJX implementation of the Panda envs: "jax" or "warp" (warp-lang, NVIDIA GPU)'
    )
    add_out_argument(parser)
    args = parser.parse_args(argv)
    target_steps = 200_000 if args.quick else 4_000_000
    max_seconds = min(args.max_seconds, 5.0) if args.quick else args.max_seconds
    env_names = [name for name in args.envs.split(",") if name in envs.names()]
    skipped = [name for name in args.envs.split(",") if name not in envs.names()]
    device = jax.devices()[0].device_kind
    devices_note = "" if jax.device_count() == 1 else f", 1 of {jax.device_count()} devices used"
    print(f"device: {device}; jax.device_count() = {jax.device_count()}{devices_note}; jax {jax.__version__}")
    if skipped:
        print(f"not registered, skipped: {', '.join(skipped)}")

    curves = {}
    configs: dict[str, PPOConfig] = {}
    for name in env_names:
        env_sizes, ppo_sizes = (safe_sizes(name, sorted(sizes)) for sizes in (args.env_sizes, args.ppo_sizes))
        configs[name] = scaling_config(name, args.impl, max([*env_sizes, *ppo_sizes, base_ppo_config(name).num_envs]))
        print(f"{name}: env stepping", flush=True)
        curves[f"{name}: env stepping"] = sweep(env_sizes, env_measure(configs[name]), target_steps, max_seconds)
        print(f"{name}: PPO training", flush=True)
        # An update is ~50x dearer per env step than stepping alone: a quarter of the work keeps large sizes in.
        curves[f"{name}: PPO training"] = sweep(ppo_sizes, ppo_measure(configs[name]), target_steps // 4, max_seconds)

    print("\n| env | measurement | parallel envs | env steps/s | compile s |")
    print("|---|---|---:|---:|---:|")
    records = []
    for label, rows in curves.items():
        name, measurement = label.split(": ")
        for size, rate, compile_seconds in rows:
            print(f"| {name} | {measurement} | {size:,} | {rate:,.0f} | {compile_seconds:.1f} |")
            records.append(
                {
                    "env": name,
                    "measurement": measurement,
                    "envs": size,
                    "env_steps_per_second": rate,
                    "compile_seconds": compile_seconds,
                }
            )

    breakdowns = {}
    for name in env_names:
        config = configs[name]
        if not any(size >= config.num_envs for size, _, _ in curves[f"{name}: PPO training"]):
            continue  # the sweep found the preset's size too slow for --max-seconds
        print(f"\nwhere a PPO update's time goes: {name}, preset {config.num_envs:,} envs (ms per update)")
        print("| phase | ms / update | share |")
        print("|---|---:|---:|")
        breakdown = time_breakdown(config, num_updates=2 if args.quick else 10)
        for phase, milliseconds in breakdown:
            share = "" if phase.startswith(" ") else f"{milliseconds / breakdown[0][1]:.0%}"
            print(f"| {phase} | {milliseconds:.1f} | {share} |")
        breakdowns[name] = [{"phase": phase.strip(), "ms_per_update": ms} for phase, ms in breakdown]

    path = pathlib.Path(args.plot)
    plot(curves, path, f"jaxarm throughput on {device} ({jax.device_count()} device(s), 1 used)")
    print(f"\nplot: {path.resolve()}")
    write_record(args.out, "scaling", argv, records, impl=args.impl, breakdown_at_preset=breakdowns, plot=str(path))
