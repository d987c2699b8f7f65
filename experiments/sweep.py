"""Sweep seeds × hyper-parameters: `python -m experiments.sweep --config NAME --seeds N key=v1,v2 ...`.

Dynamic hyper-parameters (the config's fields declared `dynamic`) of every seed and value are vmapped into one
compiled call; static choices (num_envs, sizes, ...) form separate groups, each compiled once. Writes
results.csv and results.md (mean, std and 95% CI over seeds of final return and success, the worst seed's success,
wall time) and curves.png (mean success rate and return over env steps with 95% CI bands) into the sweep directory,
a new or empty one, locked while the sweep runs: a sweep never replaces another's results. With several devices the
seeds and values are shared out over them, each run whole on one device (as many devices as divide their count);
`--local-processes N` runs the sweep as N processes of this host, one GPU each, and `--distributed` as one of
several processes on several hosts.

`--stop-after-minutes M` checkpoints every member after the chunk that passes M minutes and stops, and Ctrl-C or
SIGTERM at the next chunk end (Ctrl-C again: at once, keeping the checkpoints saved before);
`python -m experiments.sweep --resume SWEEP_DIR [--stop-after-minutes M]` continues it, computing what an
uninterrupted sweep computes. Finished groups are kept in the sweep directory (group-<k>/), the group in progress
as a checkpoint of all its members.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c()  # first, as in experiments.run: nothing is written before main()

import argparse
import csv
import dataclasses
import functools
import json
import pathlib
import shutil
import textwrap
import time
import zipfile
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from experiments import configs, distributed
from experiments.run import minutes, quiet_libraries, take_over_interrupts
from jaxarm import ranges
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import PAIR_FIELDS, RunConfig, apply_overrides
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.agents.common.sharding import ENV_AXIS, gathered, members_mesh, over_members
from jaxarm.agents.common.trainer import Trainer, run_updates
from jaxarm.exits import STOPPED_BY_SIGNAL
from jaxarm.runner import learners, paths, plots, processes, provenance, rundir, signals
from jaxarm.runner.cache import enable_compilation_cache
from jaxarm.runner.progress import explain_gspmd
from jaxarm.runner.stats import confidence_halfwidth
from jaxarm.runner.teacher import warm_start_preset

SWEEP_FILE = "sweep.json"
"""What the sweep was asked (preset, seeds, assignments), written before it trains: `--resume` reads it."""
RESULTS_FILE = "results.md"
"""The results table, a sweep's last file, written whole or not at all: a sweep holding it has finished, and one
without it resumes (a full disk at its figure left a sweep that `--resume` refused and no figure)."""
GROUP_FILE = "group.json"
CURVES_FILE = "curves.npz"
"""A finished group's results rows and curves, in its folder group-<k>/ of the sweep directory."""


class Stopped(Exception):
    """The sweep checkpointed its group in progress and stopped, at its time limit or, where `interrupted`, asked
    to (Ctrl-C, SIGTERM); `--resume` continues it."""

    def __init__(self, message: str, interrupted: bool = False):
        super().__init__(message)
        self.interrupted = interrupted


@dataclasses.dataclass(frozen=True)
class Grid:
    """A sweep: the static config groups and, inside each, the dynamic combinations to vmap."""

    groups: list[RunConfig]
    dynamic: list[dict[str, float]]


def parse_grid(base: RunConfig, assignments: list[str]) -> Grid:
    """Splits `key=v1,v2` assignments into static groups (cartesian product) and dynamic combinations, a later
    assignment of a key overriding an earlier one (a plain override, then the values swept); ValueError for a value
    given twice, or several values overridden (settings alike would share a label, and one's curve was lost)."""
    static: list[list[str]] = [[]]
    dynamic: list[dict[str, float]] = [{}]
    swept: set[str] = set()
    for item in assignments:
        key, _, values = item.partition("=")
        options = [value for value in values.split(",") if value]
        if not options:
            raise ValueError(f"sweep assignment {item!r} has no values")
        if key in swept:
            raise ValueError(f"sweep assignment {item!r} overrides the values of {key} swept before; give them once")
        if len(options) > 1:
            swept.add(key)
        is_dynamic = key in base.dynamic_fields()
        made = len(dynamic if is_dynamic else static) * len(options)
        if not ranges.AT_ONCE.admits(made):  # before the product is made: 400^3 values grew to 13 GB first
            raise ValueError(
                f"sweep assignment {key}= ({len(options):,} values) makes {made:,} settings, more than a sweep may "
                f"({ranges.AT_ONCE.describe()}); sweep fewer values"
            )
        settings = [apply_overrides(base, [f"{key}={value}"], validate=False) for value in options]
        repeated = [value for index, value in enumerate(options) if settings[index] in settings[:index]]
        if repeated:
            raise ValueError(f"sweep assignment {item!r} gives {key}={repeated[0]} twice")
        if is_dynamic:
            parsed = [apply_overrides(base, [f"{key}={value}"]) for value in options]
            dynamic = [{**combo, key: getattr(config, key)} for combo in dynamic for config in parsed]
        else:
            static = [overrides + [f"{key}={value}"] for overrides in static for value in options]
    return Grid(groups=[apply_overrides(base, overrides) for overrides in static], dynamic=dynamic)


def check_envs_at_once(grid: Grid, seeds: int) -> None:
    """ValueError where a group would step more envs at once than `ranges.AT_ONCE` admits: each of its members
    (dynamic settings × seeds) steps num_envs envs, all in one program. Checked before anything is allocated:
    `--seeds 10000000` grew until the memory limit killed it."""
    for config in grid.groups:
        envs = len(grid.dynamic) * seeds * config.num_envs
        if not ranges.AT_ONCE.admits(envs):
            raise ValueError(
                f"{len(grid.dynamic)} settings × {seeds} seeds × num_envs={config.num_envs} step {envs:,} envs at "
                f"once, more than a sweep's group may ({ranges.AT_ONCE.describe()}); sweep fewer seeds or settings"
            )


def check_no_gate(grid: Grid) -> None:
    """ValueError where a group has a gate (`retry_below`), before anything is written: a try is started again
    alone, and a sweep's runs train together in one program."""
    for config in grid.groups:
        if config.retry_below:
            raise ValueError(
                f"retry_below={config.retry_below:g} starts a run again when it fails its gate, and a sweep's runs "
                "train together in one program: give retry_below=0, or train each run with experiments.run "
                "(experiments.seeds does so for seeds)"
            )


def init_members(trainer: Trainer, keys: jax.Array, hparams, mesh: Mesh | None = None):
    """Learner states of a sweep's members, stacked: keys [M, 2] and hparams with leaves [M] -> states [M, ...],
    each device of `mesh` making its share (sharding.over_members).

    One member at a time: vmapped, the orthogonal initialisers become batched QR factorisations, and jaxlib
    0.10's CPU runtime deadlocks when two of those fan out over a two-worker pool at once (gdb: both workers in
    ParallelBatchMap's BlockingCounter::Wait inside lapack_sgeqrf, 64 seeds, 2 cores).
    """
    init = over_members(lambda k, h: jax.lax.map(lambda member: trainer.init(*member), (k, h)), mesh)
    return jax.jit(init)(keys, hparams)


def run_group(
    config: RunConfig,
    dynamic: list[dict[str, float]],
    seeds: int,
    saves: pathlib.Path | None = None,
    deadline: float | None = None,
    progress=print,
    stopping: Callable[[], bool] | None = None,
):
    """Trains every (dynamic combination × seed) of one static group in one vmapped program.

    Returns (metrics with leaves [members, updates], eval results [members, episodes], wall seconds); members
    are ordered combination-major, seed-minor. The members are shared out over as many devices (of every
    process) as divide their count, each member computed as on one device.

    With `saves` (a checkpoint folder), training continues from the latest checkpoint there, and once the clock
    (`time.perf_counter`) passes `deadline`, or `stopping()` says so (a stop asked for), with chunks left, the
    members and their metrics so far are checkpointed there and Stopped is raised. Every process calls this
    alike.
    """
    trainer = learners.make_trainer(config)
    members = [(combo, seed) for combo in dynamic for seed in range(seeds)]
    mesh = members_mesh(len(members))
    if mesh is not None:
        progress(f"  {len(members)} runs shared over {mesh.devices.size} devices")
        if processes.is_primary():
            explain_gspmd(mesh.devices.size)
    base = config.hparams()
    hparams = jax.tree.map(
        lambda *leaves: jnp.stack(leaves),
        *[base.replace(**{name: jnp.float32(value) for name, value in combo.items()}) for combo, _ in members],
    )
    keys = jnp.stack([jax.random.PRNGKey(config.seed + seed) for _, seed in members])
    start = time.perf_counter()
    state = init_members(trainer, keys, hparams, mesh)
    if config.init_from:
        if warm_start_preset(config):
            raise ValueError(
                f"init_from={config.init_from} trains a run of its own first: train it with experiments.run and give "
                "init_from=RUN"
            )
        starter = learners.warm_starter(config, pathlib.Path(config.init_from))
        state = jax.jit(over_members(jax.vmap(starter), mesh))(state)
    chunk = jax.jit(
        over_members(jax.vmap(lambda s, h: run_updates(trainer, s, h, config.chunk_updates)), mesh),
        compiler_options=trainer.compiler_options,
    )
    num_chunks = trainer.num_updates // config.chunk_updates
    done = (checkpoint.latest_step(saves) if saves is not None else None) or 0
    chunks, spent = [], 0.0
    if saves is not None and done:
        metrics, spent, state = restore_group(saves, done, jax.eval_shape(chunk, state, hparams), mesh)
        chunks.append(metrics)
        progress(f"  resumed after chunk {done}/{num_chunks}")
    for index in range(done, num_chunks):
        state, metrics = chunk(state, hparams)
        chunks.append(gathered(metrics))
        progress(f"  chunk {index + 1}/{num_chunks} ({time.perf_counter() - start:.1f} s)")
        asked = stopping is not None and stopping()
        out_of_time = deadline is not None and time.perf_counter() > deadline
        if saves is not None and processes.any_process((out_of_time or asked) and index + 1 < num_chunks):
            checkpoint.save(saves, index + 1, group_checkpoint(state, chunks, spent + time.perf_counter() - start))
            raise Stopped(
                f"{'interrupted: ' if asked else ''}stopped after chunk {index + 1}/{num_chunks} of a group, "
                f"checkpointed in {saves}",
                interrupted=asked,
            )
    metrics = joined(chunks)
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
    return metrics, gathered(results), spent + time.perf_counter() - start


def joined(chunks: list) -> object:
    """Metrics of consecutive chunks, leaves [members, updates] each -> one, concatenated along the updates."""
    return jax.tree.map(lambda *parts: np.concatenate(parts, axis=1), *chunks)


def group_checkpoint(state, chunks: list, wall: float) -> dict:
    """What a stopped group keeps: the members' state, their metrics so far and the seconds spent."""
    return {"state": state, "metrics": joined(chunks), "wall": np.float32(wall)}


def restore_group(directory: pathlib.Path, done: int, chunk_shapes, mesh: Mesh | None):
    """(metrics [members, updates so far], seconds spent, members' state) from checkpoint `done` (the chunks done)
    in `directory`; `chunk_shapes`: the (state, metrics) of one chunk, as `jax.eval_shape` gives them."""
    state_like, chunk_metrics = chunk_shapes
    like = {
        "state": state_like,
        "metrics": jax.tree.map(
            lambda leaf: jax.ShapeDtypeStruct((leaf.shape[0], leaf.shape[1] * done, *leaf.shape[2:]), leaf.dtype),
            chunk_metrics,
        ),
        "wall": jax.ShapeDtypeStruct((), jnp.float32),
    }
    shardings = None
    if mesh is not None:
        split, whole = NamedSharding(mesh, PartitionSpec(ENV_AXIS)), NamedSharding(mesh, PartitionSpec())
        shardings = {
            "state": jax.tree.map(lambda _: split, like["state"]),
            "metrics": jax.tree.map(lambda _: whole, like["metrics"]),
            "wall": whole,
        }
    restored = checkpoint.restore(directory, like, step=done, shardings=shardings)
    return gathered(restored["metrics"]), float(gathered(restored["wall"])), restored["state"]


def summarise(label: str, success: np.ndarray, returns: np.ndarray, wall: float) -> dict:
    """Per-seed final success rates and returns [seeds] -> one results row."""
    return {
        "setting": label,
        "seeds": len(success),
        "success_mean": float(success.mean()),
        "success_std": float(success.std()),
        "success_ci95": float(confidence_halfwidth(success)),
        "success_min": float(success.min()),
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "return_ci95": float(confidence_halfwidth(returns)),
        "group_wall_s": round(wall, 1),
    }


def collect(
    config: RunConfig,
    base: RunConfig,
    shared: list[str],
    dynamic: list[dict],
    seeds: int,
    metrics,
    results,
    wall: float,
):
    """One group's outputs -> (results rows, {label: (env_steps, success, return) curves [seeds, updates]}); labels
    leave out the `shared` changes.

    Training success is each seed's rolling mean over a run's curve window (`plots.rolling_window`, at least one
    time limit), weighted by the episodes each update judged; NaN where a window judged none. Returns of updates
    in which a seed finished no episode are NaN.
    """
    rows, curves = [], {}
    episodes = metrics.episodes
    finished = episodes.episodes > 0
    window = plots.rolling_window(finished.shape[1], config.updates_per_time_limit())
    success = plots.rolling_rates(episodes.success_rate, episodes.judged, window)
    env_steps = np.broadcast_to(
        np.arange(1, finished.shape[1] + 1) * config.env_steps_per_update, finished.shape
    ).astype(np.float64)
    for index, combo in enumerate(dynamic):
        members = slice(index * seeds, (index + 1) * seeds)
        label = describe(changes(config, base, combo), shared)
        rows.append(
            summarise(label, results.successes[members].mean(axis=1), results.returns[members].mean(axis=1), wall)
        )
        curves[label] = tuple(
            np.where(finished[members], values[members], np.nan) if masked else values[members]
            for values, masked in (
                (env_steps, False),
                (success, False),
                (episodes.return_mean, True),
            )
        )
    return rows, curves


def changes(config: RunConfig, base: RunConfig, combo: dict) -> list[str]:
    """What sets this (group config, dynamic combination) apart from the preset `base`, as CLI-like
    `key=value` items without spaces."""
    items = []
    for field in dataclasses.fields(config):
        value, preset = getattr(config, field.name), getattr(base, field.name)
        if field.name in PAIR_FIELDS:  # each changed pair named as on the CLI
            items += [f"{field.name}.{k}={v}" for k, v in value if (k, v) not in preset]
        elif value != preset:
            items.append(f"{field.name}={value}".replace(" ", ""))
    return items + [f"{name}={value:g}" for name, value in combo.items()]


def describe(items: list[str], shared: list[str]) -> str:
    """A setting's label: its `changes` less those every setting of the sweep shares."""
    return " ".join(item for item in items if item not in shared) or "base"


def shared_changes(grid: Grid, base: RunConfig) -> list[str]:
    """The changes from the preset that every setting of the sweep makes (said once, above the rows)."""
    each = [changes(config, base, combo) for config in grid.groups for combo in grid.dynamic]
    return [item for item in each[0] if all(item in items for items in each[1:])] if len(each) > 1 else []


def write_csv(rows: list[dict], out: pathlib.Path) -> None:
    """results.csv: one row of `rows` per setting."""
    with (out / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def results_table(rows: list[dict], shared: list[str]) -> str:
    """RESULTS_FILE's text: the changes every setting makes (`shared`), then a markdown row per setting."""
    lines = [f"Every setting: {' '.join(shared)}", ""] if shared else []
    lines += [
        "| setting | seeds | success (mean ± 95% CI) | worst seed's success | return (mean ± 95% CI) | group wall s |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    lines += [
        f"| {row['setting']} | {row['seeds']} | {row['success_mean']:.3f} ± {row['success_ci95']:.3f} | "
        f"{row['success_min']:.3f} | "
        f"{row['return_mean']:.2f} ± {row['return_ci95']:.2f} | {row['group_wall_s']} |"
        for row in rows
    ]
    return "\n".join(lines) + "\n"


def parse_args(argv: list[str]) -> argparse.Namespace:
    """`main`'s arguments; exits with the usage where they do not go together."""
    parser = argparse.ArgumentParser(
        prog="python -m experiments.sweep", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--config")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--out", type=paths.given, help="sweep directory (default runs/sweep-<config>-<timestamp>)")
    parser.add_argument("--resume", metavar="SWEEP_DIR", help="continue the stopped sweep in SWEEP_DIR")
    parser.add_argument(
        "--stop-after-minutes",
        type=minutes,
        help="checkpoint the group in progress and stop after the chunk that passes this wall time (resume later)",
    )
    distributed.add_arguments(parser, "--out")
    parser.add_argument("assignments", nargs="*", help="key=v1,v2,... (one value: a plain override)")
    args = parser.parse_args(argv)
    distributed.check_arguments(parser, args)
    if bool(args.config) == bool(args.resume):
        parser.error("give --config NAME (a new sweep) or --resume SWEEP_DIR (a stopped one)")
    if args.resume and (args.out or args.assignments):
        parser.error("--resume takes the sweep's own preset, seeds and assignments; give no --out or key=values")
    if args.distributed and not (args.out or args.resume):
        parser.error("with --distributed give --out: every process must write to the same sweep directory")
    return args


def main(argv=None) -> int:
    take_over_interrupts()  # start-up's handler had said "nothing was written" to the end
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(argv)
    if args.local_processes is not None and args.local_processes > 1:
        shared = args.resume or args.out
        if not shared:  # one directory for all of them, named here as a sweep of one names it
            shared = str(rundir.new_run_dir(f"sweep-{args.config}"))
            argv = ["--out", shared, *argv]
        return distributed.spawn(main, argv, args.local_processes, resume_command(shared))
    out: pathlib.Path | None = None
    try:
        if args.distributed:
            distributed.join(args)
        asked = read_sweep(pathlib.Path(args.resume)) if args.resume else vars(args)
        config_name, seeds, assignments = asked["config"], asked["seeds"], asked["assignments"]
        ranges.check_value("--seeds", seeds, int, ranges.COUNT)
        base = configs.get(config_name)
        grid = parse_grid(base, assignments)
        check_envs_at_once(grid, seeds)
        check_no_gate(grid)
        if args.out:
            paths.check_output_dir(pathlib.Path(args.out), "--out")
        enable_compilation_cache()
        if args.resume:
            out = pathlib.Path(args.resume)
        else:
            out = pathlib.Path(args.out) if args.out else rundir.new_run_dir(f"sweep-{config_name}")
        run_sweep(args, out, asked, base, grid)
    except Stopped as stopped:
        return stopped_status(stopped, out)
    except KeyboardInterrupt:  # before the sweep trains (or in a process that is not the main thread's)
        print(f"\ninterrupted{resumable(out) or ': nothing was trained'}", file=sys.stderr)
        quiet_libraries()
        return STOPPED_BY_SIGNAL
    except checkpoint.CheckpointError as error:  # a group's checkpoint could not be written (a full disk)
        distributed.ignore_stop_signals_in_a_job(args)
        distributed.leave_if_peers_lost(error, resume_command(out))  # or a peer gone while it was written
        print(f"error: {error}{resumable(out)}", file=sys.stderr)
        quiet_libraries()
        return 2
    except ValueError as error:
        distributed.ignore_stop_signals_in_a_job(args)
        print(f"error: {error}", file=sys.stderr)
        return 2
    except jax.errors.JaxRuntimeError as error:  # a collective's, where a peer has gone
        distributed.ignore_stop_signals_in_a_job(args)
        distributed.leave_if_peers_lost(error, resume_command(out))
        raise
    except OSError as error:
        distributed.ignore_stop_signals_in_a_job(args)
        print(f"error: {paths.os_error_message(error, out)}{resumable(out)}", file=sys.stderr)
        quiet_libraries()
        return 2
    return 0


def run_sweep(args: argparse.Namespace, out: pathlib.Path, asked: dict, base: RunConfig, grid: Grid) -> None:
    """Trains the sweep `asked` ({"config", "seeds", "assignments"}; `base` and `grid` read from it) into `out` as
    `args` say, process 0 alone writing it (under its lock). From here Ctrl-C and SIGTERM stop it at a chunk end,
    with its group in progress checkpointed (Stopped)."""
    config_name, seeds, assignments = asked["config"], asked["seeds"], asked["assignments"]
    title = f"{config_name}, {seeds} seeds"
    stop_after_s = None if args.stop_after_minutes is None else 60 * args.stop_after_minutes
    stop = signals.StopRequests(aborted=continue_with(out))
    with stop.installed():
        if not processes.is_primary():  # every process trains its members; process 0 alone writes results
            sweep(base, grid, seeds, out, title, stop_after_s, primary=False, stopping=lambda: stop.requested)
            return
        with rundir.locked(out, check=check_stopped_sweep if args.resume else rundir.check_empty):
            if args.resume:
                provenance.append_provenance(out, "sweep resumed")
            else:
                provenance.append_provenance(out, "sweep")
                asked = {"config": config_name, "seeds": seeds, "assignments": assignments}
                rundir.write_json(out / SWEEP_FILE, asked)
            sweep(base, grid, seeds, out, title, stop_after_s, stopping=lambda: stop.requested)


def stopped_status(stopped: Stopped, out: pathlib.Path | None) -> int:
    """Says how the sweep in `out` goes on after `stopped` (process 0); the exit status: STOPPED_BY_SIGNAL where a
    signal stopped it, 0 where its time limit did."""
    if stopped.interrupted:
        if processes.is_primary():
            print(f"{stopped}{continue_with(out)}", file=sys.stderr)
        quiet_libraries()
        return STOPPED_BY_SIGNAL
    if processes.is_primary():
        print(f"{stopped}{continue_with(out)}")
    return 0


def resume_command(out: str | pathlib.Path | None) -> str:
    """The command that goes on with the sweep in `out`."""
    return f"python -m experiments.sweep --resume {out}"


def continue_with(out: pathlib.Path | None) -> str:
    """How a message ends that says how to go on with the sweep in `out`."""
    return f"; continue with: {resume_command(out)}"


def resumable(out: pathlib.Path | None) -> str:
    """`continue_with(out)` where `out` holds a sweep that `--resume` takes (its sweep.json, no results yet), else
    nothing."""
    if out is None or not (out / SWEEP_FILE).exists() or (out / RESULTS_FILE).exists():
        return ""
    return continue_with(out)


def read_sweep(directory: pathlib.Path) -> dict:
    """What the sweep in `directory` was asked ({"config", "seeds", "assignments"}); ValueError where there is no
    stopped sweep there to resume."""
    path = directory / SWEEP_FILE
    if not path.exists():
        raise ValueError(f"{directory} holds no sweep to resume (no {SWEEP_FILE})")
    if (directory / RESULTS_FILE).exists():
        raise ValueError(f"the sweep in {directory} has finished: its results are in {directory / RESULTS_FILE}")
    try:
        asked = json.loads(path.read_text())
        check_asked(asked)
    except ValueError as error:  # JSONDecodeError and UnicodeDecodeError among them
        raise ValueError(
            f"{path} is corrupt or edited ({error}); restore it, or start the sweep again in a new directory"
        ) from None
    return asked


def check_asked(asked) -> None:
    """ValueError naming the field where `asked` (sweep.json's content) is not what `main` writes there: an object
    with a preset's name, a count of seeds and a list of assignment strings."""
    if not isinstance(asked, dict):
        raise ValueError(f"not a JSON object but {type(asked).__name__}")
    missing = [name for name in ("config", "seeds", "assignments") if name not in asked]
    if missing:
        raise ValueError(f"no {', '.join(missing)}")
    ranges.check_value("config", asked["config"], str, None)
    ranges.check_value("seeds", asked["seeds"], int, ranges.COUNT)
    if not isinstance(asked["assignments"], list):
        raise ValueError(f"assignments must be a list of 'key=v1,v2' strings, got {asked['assignments']!r}")
    ranges.check_value("assignments", tuple(asked["assignments"]), tuple[str, ...], None)


def check_stopped_sweep(directory: pathlib.Path) -> None:
    """ValueError unless `directory` holds a stopped sweep (the lock's check for `--resume`)."""
    read_sweep(directory)


def write_group(folder: pathlib.Path, rows: list[dict], curves: dict) -> None:
    """Keeps a finished group's results rows and curves in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    labels = list(curves)
    np.savez(
        folder / CURVES_FILE,
        **{f"{k}_{j}": part for k, label in enumerate(labels) for j, part in enumerate(curves[label])},
    )
    rundir.write_json(folder / GROUP_FILE, {"rows": rows, "labels": labels})


def read_group(folder: pathlib.Path) -> tuple[list[dict], dict] | None:
    """A finished group's (results rows, curves) kept in `folder`, or None where it has not finished; ValueError in
    one line where its files are damaged or edited (a resume met JSON's, numpy's or a KeyError's traceback)."""
    if not (folder / GROUP_FILE).exists():
        return None
    try:
        kept = json.loads((folder / GROUP_FILE).read_text())
        rows, labels = kept["rows"], kept["labels"]
        if not (isinstance(rows, list) and isinstance(labels, list) and len(rows) == len(labels) > 0):
            raise TypeError("no rows and labels, one of each per setting")
        with np.load(folder / CURVES_FILE) as parts:
            curves = {label: tuple(parts[f"{k}_{j}"] for j in range(3)) for k, label in enumerate(labels)}
    except (FileNotFoundError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as error:
        raise ValueError(
            f"{folder}, a finished group, is damaged or edited ({type(error).__name__}: {error}); delete it to train "
            "that group again"
        ) from None
    return rows, curves


def silent(line: str) -> None:
    """The progress of a process that prints none (not the primary)."""


def sweep(
    base: RunConfig,
    grid: Grid,
    seeds: int,
    out: pathlib.Path,
    title: str,
    stop_after_s: float | None = None,
    primary: bool = True,
    stopping: Callable[[], bool] | None = None,
) -> None:
    """Trains every group of `grid` not yet finished in `out` and, where `primary`, writes the tables and curves
    into `out` (the other processes of a distributed sweep only train and checkpoint). Raises Stopped once
    `stop_after_s` seconds have passed with a group unfinished (its checkpoint in `out`), or once `stopping()` says
    so, at a chunk end or between groups."""
    deadline = None if stop_after_s is None else time.perf_counter() + stop_after_s
    # Every process reaches the same lines: the primary's alone reach the console, once.
    progress = functools.partial(print, flush=True) if primary else silent
    rows: list[dict] = []
    curves: dict = {}
    shared = shared_changes(grid, base)
    for index, config in enumerate(grid.groups):
        folder = out / f"group-{index}"
        finished = read_group(folder)
        if finished is None:
            progress(f"group {describe(changes(config, base, {}), [])}: {len(grid.dynamic)} settings × {seeds} seeds")
            saves = folder / "checkpoints"
            metrics, results, wall = run_group(
                config, grid.dynamic, seeds, saves, deadline, progress=progress, stopping=stopping
            )
            finished = collect(config, base, shared, grid.dynamic, seeds, metrics, results, wall)
            if primary:
                write_group(folder, *finished)
                shutil.rmtree(saves, ignore_errors=True)  # its members' state: kept results suffice
            asked = stopping is not None and stopping()
            if processes.any_process(asked and index + 1 < len(grid.groups)):
                raise Stopped(
                    f"interrupted: stopped after group {index + 1}/{len(grid.groups)}, kept in {folder}", True
                )
        rows += finished[0]
        curves.update(finished[1])
    if not primary:
        return
    write_csv(rows, out)
    plots.sweep_curves(curves, out / "curves.png", title="\n".join([title, *textwrap.wrap(" ".join(shared), 110)]))
    rundir.write_text(out / RESULTS_FILE, results_table(rows, shared))
    print((out / RESULTS_FILE).read_text())
    print(f"wrote {out}/results.csv, results.md, curves.png")


if __name__ == "__main__":
    start_up.exit_with(main)
