"""Sweep seeds × hyper-parameters: `python -m experiments.sweep --config NAME --seeds N key=v1,v2 ...`.

Dynamic hyper-parameters (the config's fields declared `dynamic`) of every seed and value are vmapped into one
compiled call; static choices (num_envs, sizes, ...) form separate groups, each compiled once. Writes
results.csv and results.md (mean, std and 95% CI over seeds of final return and success, wall time) and
curves.png (mean success rate and return over env steps with 95% CI bands) into the sweep directory, a new or
empty one, locked while the sweep runs: a sweep never replaces another's results. With several devices the
seeds and values are shared out over them, each run whole on one device (as many devices as divide their count).
"""

import argparse
import csv
import dataclasses
import pathlib
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh

from experiments import configs, distributed
from jaxarm.agents.common.config import RunConfig, apply_overrides
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.agents.common.sharding import gathered, members_mesh, over_members
from jaxarm.agents.common.trainer import Trainer, run_updates
from jaxarm.runner import plots, processes, rundir
from jaxarm.runner.cache import enable_compilation_cache
from jaxarm.runner.stats import confidence_halfwidth


@dataclasses.dataclass(frozen=True)
class Grid:
    """A sweep: the static config groups and, inside each, the dynamic combinations to vmap."""

    groups: list[RunConfig]
    dynamic: list[dict[str, float]]


def parse_grid(base: RunConfig, assignments: list[str]) -> Grid:
    """Splits `key=v1,v2` assignments into static groups (cartesian product) and dynamic combinations."""
    static: list[list[str]] = [[]]
    dynamic: list[dict[str, float]] = [{}]
    for item in assignments:
        key, _, values = item.partition("=")
        options = [value for value in values.split(",") if value]
        if not options:
            raise ValueError(f"sweep assignment {item!r} has no values")
        if key in base.dynamic_fields():
            parsed = [apply_overrides(base, [f"{key}={value}"]) for value in options]
            dynamic = [{**combo, key: getattr(config, key)} for combo in dynamic for config in parsed]
        else:
            static = [overrides + [f"{key}={value}"] for overrides in static for value in options]
    return Grid(groups=[apply_overrides(base, overrides) for overrides in static], dynamic=dynamic)


def init_members(trainer: Trainer, keys: jax.Array, hparams, mesh: Mesh | None = None):
    """Learner states of a sweep's members, stacked: keys [M, 2] and hparams with leaves [M] -> states [M, ...],
    each device of `mesh` making its share (sharding.over_members).

    One member at a time: vmapped, the orthogonal initialisers become batched QR factorisations, and jaxlib
    0.10's CPU runtime deadlocks when two of those fan out over a two-worker pool at once (gdb: both workers in
    ParallelBatchMap's BlockingCounter::Wait inside lapack_sgeqrf, 64 seeds, 2 cores).
    """
    init = over_members(lambda k, h: jax.lax.map(lambda member: trainer.init(*member), (k, h)), mesh)
    return jax.jit(init)(keys, hparams)


def run_group(config: RunConfig, dynamic: list[dict[str, float]], seeds: int, progress=print):
    """Trains every (dynamic combination × seed) of one static group in one vmapped program.

    Returns (metrics with leaves [members, updates], eval results [members, episodes], wall seconds); members
    are ordered combination-major, seed-minor. The members are shared out over as many devices (of every
    process) as divide their count, each member computed as on one device.
    """
    trainer = configs.make_trainer(config)
    members = [(combo, seed) for combo in dynamic for seed in range(seeds)]
    mesh = members_mesh(len(members))
    if mesh is not None:
        progress(f"  {len(members)} runs shared over {mesh.devices.size} devices")
    base = config.hparams()
    hparams = jax.tree.map(
        lambda *leaves: jnp.stack(leaves),
        *[base.replace(**{name: jnp.float32(value) for name, value in combo.items()}) for combo, _ in members],
    )
    keys = jnp.stack([jax.random.PRNGKey(config.seed + seed) for _, seed in members])
    start = time.perf_counter()
    state = init_members(trainer, keys, hparams, mesh)
    if config.init_from:
        state = jax.jit(over_members(jax.vmap(rundir.warm_starter(config)), mesh))(state)
    chunk = jax.jit(
        over_members(jax.vmap(lambda s, h: run_updates(trainer, s, h, config.chunk_updates)), mesh),
        compiler_options=trainer.compiler_options,
    )
    chunks = []
    for index in range(trainer.num_updates // config.chunk_updates):
        state, metrics = chunk(state, hparams)
        chunks.append(gathered(metrics))
        progress(
            f"  chunk {index + 1}/{trainer.num_updates // config.chunk_updates} ({time.perf_counter() - start:.1f} s)"
        )
    metrics = jax.tree.map(lambda *parts: np.concatenate(parts, axis=1), *chunks)
    env, env_params = config.make_eval_env()
    eval_keys = jax.random.split(jax.random.PRNGKey(config.seed + 1_000_003), len(members))
    results = jax.jit(
        over_members(
            jax.vmap(
                lambda learner, key: evaluate(
                    env, env_params, lambda obs: trainer.act(learner, obs), key, config.eval_episodes
                )
            ),
            mesh,
        )
    )(state, eval_keys)
    return metrics, gathered(results), time.perf_counter() - start


def summarise(label: str, success: np.ndarray, returns: np.ndarray, wall: float) -> dict:
    """Per-seed final success rates and returns [seeds] -> one results row."""
    return {
        "setting": label,
        "seeds": len(success),
        "success_mean": float(success.mean()),
        "success_std": float(success.std()),
        "success_ci95": float(confidence_halfwidth(success)),
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "return_ci95": float(confidence_halfwidth(returns)),
        "group_wall_s": round(wall, 1),
    }


def collect(config: RunConfig, base: RunConfig, dynamic: list[dict], seeds: int, metrics, results, wall: float):
    """One group's outputs -> (results rows, {label: (env_steps, success, return) curves [seeds, updates]}).

    Curve points of updates in which a seed finished no episode are NaN.
    """
    rows, curves = [], {}
    finished = metrics.episodes.episodes > 0
    env_steps = np.broadcast_to(
        np.arange(1, finished.shape[1] + 1) * config.env_steps_per_update, finished.shape
    ).astype(np.float64)
    for index, combo in enumerate(dynamic):
        members = slice(index * seeds, (index + 1) * seeds)
        label = describe(config, base, combo)
        rows.append(
            summarise(label, results.successes[members].mean(axis=1), results.returns[members].mean(axis=1), wall)
        )
        curves[label] = tuple(
            np.where(finished[members], values[members], np.nan) if masked else values[members]
            for values, masked in (
                (env_steps, False),
                (metrics.episodes.success_rate, True),
                (metrics.episodes.return_mean, True),
            )
        )
    return rows, curves


def describe(config: RunConfig, base: RunConfig, combo: dict) -> str:
    changed = [
        f"{field.name}={getattr(config, field.name)}"
        for field in dataclasses.fields(config)
        if getattr(config, field.name) != getattr(base, field.name)
    ]
    return " ".join(changed + [f"{name}={value:g}" for name, value in combo.items()]) or "base"


def write_tables(rows: list[dict], out: pathlib.Path) -> None:
    with (out / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    lines = [
        "| setting | seeds | success (mean ± 95% CI) | return (mean ± 95% CI) | group wall s |",
        "|---|---:|---:|---:|---:|",
    ]
    lines += [
        f"| {row['setting']} | {row['seeds']} | {row['success_mean']:.3f} ± {row['success_ci95']:.3f} | "
        f"{row['return_mean']:.2f} ± {row['return_ci95']:.2f} | {row['group_wall_s']} |"
        for row in rows
    ]
    (out / "results.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.sweep", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--config", required=True)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--out", help="sweep directory (default runs/sweep-<config>-<timestamp>)")
    distributed.add_arguments(parser, "--out")
    parser.add_argument("assignments", nargs="*", help="key=v1,v2,... (one value: a plain override)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    distributed.check_arguments(parser, args)
    if args.distributed and not args.out:
        parser.error("with --distributed give --out: every process must write to the same sweep directory")
    try:
        if args.distributed:
            distributed.join(args)
        if args.seeds <= 0:
            raise ValueError(f"--seeds must be positive, got {args.seeds}")
        base = configs.get(args.config)
        grid = parse_grid(base, args.assignments)
        if args.out:
            rundir.check_output_dir(pathlib.Path(args.out), "--out")
        enable_compilation_cache()
        out = pathlib.Path(args.out) if args.out else rundir.new_run_dir(f"sweep-{args.config}")
        title = f"{args.config}, {args.seeds} seeds"
        if not processes.is_primary():  # every process trains its members; process 0 alone writes
            sweep(base, grid, args.seeds, None, title)
            return 0
        with rundir.locked(out, check=rundir.check_empty):
            rundir.append_provenance(out, "sweep")
            sweep(base, grid, args.seeds, out, title)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"error: {rundir.os_error_message(error)}", file=sys.stderr)
        return 2
    return 0


def sweep(base: RunConfig, grid: Grid, seeds: int, out: pathlib.Path | None, title: str) -> None:
    """Trains every group of `grid` and writes the tables and curves into `out` (None: writes nothing, as a
    process other than the first of a distributed sweep)."""
    rows, curves = [], {}
    for config in grid.groups:
        print(f"group {describe(config, base, {})}: {len(grid.dynamic)} settings × {seeds} seeds", flush=True)
        metrics, results, wall = run_group(config, grid.dynamic, seeds)
        group_rows, group_curves = collect(config, base, grid.dynamic, seeds, metrics, results, wall)
        rows += group_rows
        curves.update(group_curves)
    if out is None:
        return
    write_tables(rows, out)
    plots.sweep_curves(curves, out / "curves.png", title=title)
    print((out / "results.md").read_text())
    print(f"wrote {out}/results.csv, results.md, curves.png")


if __name__ == "__main__":
    sys.exit(main())
