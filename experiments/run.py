"""Train a named config: `python -m experiments.run --config NAME [key=value ...]`.

The learner is compiled in chunks of `updates_per_chunk` updates; between chunks the runner logs metrics
(JSON lines, TensorBoard), shows progress, checks for NaN/inf and checkpoints the whole learner state.
`--resume RUN_DIR` continues from the latest checkpoint; on CPU the result is bit-identical to an
uninterrupted run. With several devices the env batch is split across all of them (data parallel, see
jaxarm/agents/common/sharding.py). At the end it evaluates the deterministic policy and draws the curve.
"""

import argparse
import json
import pathlib
import sys
import time
from collections.abc import Callable

import jax
import numpy as np

from experiments import configs, plots, progress, rundir
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import apply_overrides
from jaxarm.agents.common.sharding import data_mesh, data_parallel
from jaxarm.agents.common.trainer import make_chunk_runner


class TrainingDiverged(RuntimeError):
    """NaN or inf appeared in the metrics or the learner state."""


def parse_args(argv):
    parser = argparse.ArgumentParser(prog="python -m experiments.run", description=__doc__.splitlines()[0])
    parser.add_argument("--config", help="preset name (see --list)")
    parser.add_argument("--list", action="store_true", help="list presets and exit")
    parser.add_argument("--out", help="run directory (default runs/<config>-<timestamp>)")
    parser.add_argument("--resume", help="continue the run in this directory from its latest checkpoint")
    parser.add_argument(
        "--stop-after-minutes",
        type=float,
        help="checkpoint and stop after the chunk that passes this wall time (resume later)",
    )
    parser.add_argument(
        "--distributed",
        action="store_true",
        help="call jax.distributed.initialize() first (multi-host: run the same command on every host)",
    )
    parser.add_argument("overrides", nargs="*", help="config overrides key=value (env_params.NAME=VALUE too)")
    args = parser.parse_args(argv)
    if not (args.list or args.config or args.resume):
        parser.error("give --config NAME, --resume RUN_DIR or --list")
    if args.resume and (args.config or args.overrides):
        parser.error("--resume takes the config saved in the run directory; give no --config or overrides")
    return args


def first_non_finite(flat_metrics: dict[str, np.ndarray]) -> tuple[int, str] | None:
    """(index within the chunk, metric name) of the first NaN/inf, or None."""
    found = [
        (int(np.argmax(~np.isfinite(values))), name)
        for name, values in flat_metrics.items()
        if not np.all(np.isfinite(values))
    ]
    return min(found) if found else None


def state_is_finite(state) -> bool:
    leaves = [leaf for leaf in jax.tree.leaves(state) if np.issubdtype(np.asarray(leaf).dtype, np.floating)]
    return all(bool(np.all(np.isfinite(np.asarray(leaf)))) for leaf in leaves)


def metric_rows(flat: dict[str, np.ndarray], first_update: int, wall_time: float, steps_per_second: float):
    count = len(next(iter(flat.values())))
    for index in range(count):
        row = {"updates": first_update + index + 1, "wall_time": wall_time, "steps_per_second": steps_per_second}
        row.update({name: float(values[index]) for name, values in flat.items()})
        yield row


def train(config, preset: str, run_dir: pathlib.Path, resume: bool, stop_after_s: float | None = None) -> dict:
    """Trains (or resumes) into `run_dir`; returns the evaluation. Raises TrainingDiverged on NaN.

    With `stop_after_s`, the first chunk that ends past that many seconds of this call is checkpointed and
    training stops there (the evaluation then describes that state; `--resume` continues).
    """
    from tensorboardX import SummaryWriter

    trainer = configs.make_trainer(config)
    hparams = config.hparams()
    checkpoints = run_dir / "checkpoints"
    if resume:
        state = rundir.restore_state(run_dir, trainer, config)
        done_updates = int(state.updates)
        rundir.truncate_metrics(run_dir, done_updates)
        wall_offset = max([row["wall_time"] for row in rundir.read_metrics(run_dir)], default=0.0)
    else:
        state = jax.jit(trainer.init)(jax.random.PRNGKey(config.seed), hparams)
        if config.init_from:
            state = rundir.warm_starter(config)(state)
        # Written once the start state exists: a warm start that fails leaves no half-made run directory.
        rundir.write_config(run_dir, config, preset)
        done_updates, wall_offset = 0, 0.0
    if jax.device_count() > 1:
        state = data_parallel(state, data_mesh())
    runners: dict[int, Callable] = {}
    writer = SummaryWriter(str(run_dir / "tensorboard"))
    last_saved = done_updates
    start = time.perf_counter()
    with (
        progress.Progress(trainer.num_updates * trainer.env_steps_per_update) as bar,
        (run_dir / "metrics.jsonl").open("a") as log,
    ):
        bar.advance_to(done_updates * trainer.env_steps_per_update)
        while done_updates < trainer.num_updates:
            count = min(config.updates_per_chunk, trainer.num_updates - done_updates)
            runner = runners.setdefault(count, make_chunk_runner(trainer, count))
            chunk_start = time.perf_counter()
            state, metrics = runner(state, hparams)
            flat = rundir.flatten_metrics(jax.device_get(metrics))
            chunk_time = time.perf_counter() - chunk_start
            bad = first_non_finite(flat)
            if bad is not None or not state_is_finite(state):
                where = (
                    f"update {done_updates + bad[0] + 1} ({bad[1]})"
                    if bad
                    else f"updates {done_updates + 1}-{done_updates + count}"
                )
                raise TrainingDiverged(
                    f"NaN or inf at {where}; training stopped. The last good checkpoint "
                    f"(update {checkpoint.latest_step(checkpoints)}) in {checkpoints} is intact."
                )
            wall = wall_offset + time.perf_counter() - start
            rate = count * trainer.env_steps_per_update / chunk_time
            for row in metric_rows(flat, done_updates, wall, rate):
                log.write(json.dumps(row) + "\n")
                for name, value in row.items():
                    writer.add_scalar(name, value, row["updates"])
            log.flush()
            done_updates += count
            out_of_time = stop_after_s is not None and time.perf_counter() - start > stop_after_s
            if (
                done_updates - last_saved >= config.checkpoint_every_updates
                or done_updates == trainer.num_updates
                or out_of_time
            ):
                checkpoint.save(checkpoints, done_updates, state)
                last_saved = done_updates
            bar.update(done_updates * trainer.env_steps_per_update, rate, flat)
            if out_of_time:
                break
    writer.close()
    train_time = wall_offset + time.perf_counter() - start
    result = rundir.evaluate_state(trainer, config, state, config.eval_episodes, seed=config.seed + 1_000_003)
    result["train_wall_time"] = train_time
    result["env_steps"] = int(state.env_steps)
    result["finished"] = done_updates == trainer.num_updates
    rundir.write_json(run_dir / "eval.json", result)
    plots.learning_curve(rundir.read_metrics(run_dir), run_dir / "curve.png", title=preset)
    return result


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.distributed:
        jax.distributed.initialize()
    if args.list:
        for name, description in configs.describe().items():
            print(f"{name:24s} {description}")
        return 0
    try:
        if args.resume:
            run_dir = pathlib.Path(args.resume)
            config, preset = rundir.read_config(run_dir)
        else:
            preset = args.config
            config = apply_overrides(configs.get(preset), args.overrides)
            run_dir = pathlib.Path(args.out) if args.out else rundir.new_run_dir(preset)
            if (run_dir / "config.json").exists():
                raise ValueError(f"{run_dir} already holds a run; use --resume {run_dir} or another --out")
        stop_after_s = None if args.stop_after_minutes is None else 60 * args.stop_after_minutes
        result = train(config, preset, run_dir, resume=bool(args.resume), stop_after_s=stop_after_s)
    except (ValueError, checkpoint.CheckpointError, TrainingDiverged) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(
        f"{run_dir}: success_rate {result['success_rate']:.3f}, return_mean {result['return_mean']:.2f}, "
        f"{result['env_steps']:,} env steps in {result['train_wall_time']:.1f} s on {result['device']}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
