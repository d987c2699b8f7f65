"""Compare finished or stopped runs: `python -m experiments.compare RUN_DIR ... [--out PNG]`.

For studies whose points are separate runs (a batch-size study stopped at equal wall clock with
`run.py --stop-after-minutes`, or runs from several sessions): reads each run's config.json, metrics.jsonl and,
where present, eval.json; prints a markdown table (batch, steady env steps/s, env steps, wall clock, training
success and return at the end and at the wall clock all runs reached, the best evaluation during training and
the final one) and draws the success rate and training return over env steps and over wall clock, runs
overlaid: on the success panels the evaluations during training (`eval_every_updates`) first, solid with dots,
and the training success dashed. Training success counts every training episode, curricula starts included (and
an env's first episode as a failure until it ends: `jaxarm.agents.common.trainer.summarise_episodes`), so it
compares runs of one preset, not with evaluations; evaluations compare any runs of one task.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c(start_up.AT_ONCE)  # first: Ctrl-C ends it at once, from its first import on

import argparse
import dataclasses
import os
import pathlib

import numpy as np

from jaxarm.runner import metrics_log, paths, plots, rundir


@dataclasses.dataclass(frozen=True)
class RunCurves:
    """One run's training curves, over updates in which at least one episode finished.

    Attributes:
      label: the run directory's name, or the label given.
      batch: env steps per update (num_envs × rollout_length; None where the config has no rollout).
      env_steps, wall_seconds: [U] env steps and seconds since the first jit at each update (every update of a
        chunk logs the chunk's end).
      update_seconds: [U] `wall_seconds` with each chunk's updates spread evenly over its seconds
        (`update_times`): what curves over wall clock are drawn against.
      success, returns: [U] rolling means of the training success rate (weighted by the episodes each update
        judged) and of the episode return (by those it finished).
      steps_per_second: the median env-steps rate after the first logged chunk (compile excluded).
      evaluation: eval.json's contents, or None.
      eval_env_steps, eval_wall_seconds, eval_success: [E] the evaluations during training: env steps and
        seconds when each ran, and the success rate of its fresh episodes (E = 0 where the run made none).
    """

    label: str
    batch: int | None
    env_steps: np.ndarray
    wall_seconds: np.ndarray
    update_seconds: np.ndarray
    success: np.ndarray
    returns: np.ndarray
    steps_per_second: float
    evaluation: dict | None
    eval_env_steps: np.ndarray
    eval_wall_seconds: np.ndarray
    eval_success: np.ndarray


def load_run(run_dir: pathlib.Path, label: str | None = None) -> RunCurves:
    """Reads a run directory; ValueError if it holds no finished episodes."""
    config, _ = rundir.read_config(run_dir)
    metrics = metrics_log.read_metrics(run_dir)
    ended = update_times(np.array([row["wall_time"] for row in metrics], float))
    kept = [index for index, row in enumerate(metrics) if row.get("episodes/episodes", 0) > 0]
    rows = [metrics[index] for index in kept]
    evaluations = [row for row in metrics if "eval/success_rate" in row]
    if not rows:
        raise ValueError(f"{run_dir} has no metrics with finished episodes")

    def column(name: str) -> np.ndarray:
        return np.array([row[name] for row in rows], float)

    episodes = column("episodes/episodes")
    window = plots.rolling_window(len(rows), config.updates_per_time_limit())  # as in the run's own curve
    wall = column("wall_time")
    rates = column("steps_per_second")[wall > wall[0]]
    rollout = getattr(config, "rollout_length", None)
    return RunCurves(
        label=label or run_dir.name,
        batch=config.num_envs * rollout if rollout else None,
        env_steps=column("env_steps"),
        wall_seconds=wall,
        update_seconds=ended[kept],
        success=plots.rolling_mean(column("episodes/success_rate"), window, plots.success_weights(rows)),
        returns=plots.rolling_mean(column("episodes/return_mean"), window, episodes),
        steps_per_second=float(np.median(rates)) if len(rates) else float("nan"),
        evaluation=rundir.read_evaluation(run_dir) or None,
        eval_env_steps=np.array([row["env_steps"] for row in evaluations], float),
        eval_wall_seconds=np.array([row["wall_time"] for row in evaluations], float),
        eval_success=np.array([row["eval/success_rate"] for row in evaluations], float),
    )


def value_at(run: RunCurves, values: np.ndarray, seconds: float) -> float:
    """`values` [U] at the last update logged by `seconds` of wall clock (NaN before the first)."""
    reached = np.flatnonzero(run.wall_seconds <= seconds)
    return float(values[reached[-1]]) if len(reached) else float("nan")


def value_cell(value: float, spec: str) -> str:
    """`value` formatted by `spec`, or "—" for NaN (a run that had logged nothing by then)."""
    return "—" if np.isnan(value) else format(value, spec)


def table(runs: list[RunCurves]) -> str:
    """Markdown: one row per run, with training success and return also at the wall clock every run reached."""
    common = min(run.wall_seconds[-1] for run in runs)
    lines = [
        f"| run | env steps per update | env steps/s | env steps | wall s | training success | return | "
        f"success at {common:.0f} s | return at {common:.0f} s | best eval during training (env steps, s) | "
        "eval success |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for run in runs:
        evaluated = f"{run.evaluation['success_rate']:.1%} ({run.evaluation['episodes']:,})" if run.evaluation else "—"
        best = "—"
        if len(run.eval_success):
            index = int(np.argmax(run.eval_success))
            best = (
                f"{run.eval_success[index]:.1%} ({run.eval_env_steps[index]:,.0f}, {run.eval_wall_seconds[index]:.0f})"
            )
        batch = f"{run.batch:,}" if run.batch else "—"
        lines.append(
            f"| {run.label} | {batch} | {run.steps_per_second:,.0f} | {run.env_steps[-1]:,.0f} | "
            f"{run.wall_seconds[-1]:.0f} | {run.success[-1]:.1%} | {run.returns[-1]:.1f} | "
            f"{value_cell(value_at(run, run.success, common), '.1%')} | "
            f"{value_cell(value_at(run, run.returns, common), '.1f')} | "
            f"{best} | {evaluated} |"
        )
    return "\n".join(lines)


def update_times(chunk_ends: np.ndarray) -> np.ndarray:
    """[U] seconds at which each update ended, from `chunk_ends` [U], the wall clock each metrics row logs: every
    update of a chunk logs the chunk's end. Each chunk's updates are spread evenly over its own seconds, so that a
    curve over wall clock rises as training went rather than in a vertical step per chunk."""
    times = np.empty_like(chunk_ends)
    firsts = np.flatnonzero(np.r_[True, np.diff(chunk_ends) != 0])
    previous = 0.0
    for begin, end in zip(firsts, [*firsts[1:], len(chunk_ends)], strict=True):
        count = end - begin
        times[begin:end] = previous + (chunk_ends[begin] - previous) * np.arange(1, count + 1) / count
        previous = chunk_ends[begin]
    return times


def device_name(runs: list[RunCurves], given: str | None) -> str:
    """The device for the figure's title: the one every evaluated run names, or `given`, which must be part of
    the device every evaluated run names (case aside: "H100" for "NVIDIA H100 80GB HBM3") so that runs are never
    labelled with a device they did not run on; ValueError otherwise."""
    recorded = {run.label: run.evaluation["device"] for run in runs if run.evaluation and "device" in run.evaluation}
    if given:
        elsewhere = {label: device for label, device in recorded.items() if given.lower() not in device.lower()}
        if elsewhere:
            shown = ", ".join(f"{label} on {device!r}" for label, device in elsewhere.items())
            raise ValueError(f"--device {given!r} does not name the device of every run: {shown}")
        return given
    named = set(recorded.values())
    if len(named) != 1:
        raise ValueError(
            f"name the device for the figure with --device (the runs' eval.json files name {sorted(named) or 'none'})"
        )
    return named.pop()


FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def figure_path(out: pathlib.Path) -> pathlib.Path:
    """Where `--out` puts the figure: `out` itself for a .png, .pdf or .svg name, `out/compare.png` for a
    directory, `out.png` for a name without a suffix. ValueError naming `out` for another suffix or a file in the
    way of its folder; missing folders are made."""
    paths.check_not_under_a_file(out, "--out")
    if out.is_dir():
        out = out / "compare.png"
    elif not out.suffix:
        out = out.with_suffix(".png")
    if out.suffix.lower() not in FIGURE_SUFFIXES:
        raise ValueError(f"--out {out}: the figure is written as {', '.join(FIGURE_SUFFIXES)}; name one of those")
    return out


def default_out(run_dirs: list[str]) -> pathlib.Path:
    """compare.png in the directory that holds the runs (their nearest common one), not the working directory."""
    parents = [str(pathlib.Path(path).resolve().parent) for path in run_dirs]
    return pathlib.Path(os.path.commonpath(parents)) / "compare.png"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.compare", description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", nargs="+")
    parser.add_argument(
        "--label",
        action="append",
        dest="labels",
        help="a run's label; give one per run, in order (default: directory names)",
    )
    parser.add_argument("--title", default="runs compared")
    parser.add_argument(
        "--device",
        help="device named in the figure, for runs without an eval.json (default: the runs' eval.json; a name "
        "that is not part of a run's recorded device is refused)",
    )
    parser.add_argument(
        "--out",
        type=paths.given,
        help="the figure (.png, .pdf or .svg; a directory gets compare.png; default: beside the runs)",
    )
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    labels = args.labels or [None] * len(args.run_dirs)
    try:
        if len(labels) != len(args.run_dirs):
            raise ValueError(f"{len(labels)} --label for {len(args.run_dirs)} runs")
        runs = [load_run(pathlib.Path(path), label) for path, label in zip(args.run_dirs, labels, strict=True)]
        alike = sorted({run.label for run in runs if [other.label for other in runs].count(run.label) > 1})
        if alike:  # the figure's curves are keyed by label: one of each pair was drawn, the other left out
            raise ValueError(f"runs share the label {alike[0]!r}; give each a --label of its own, in order")
        device = device_name(runs, args.device)
        out = figure_path(pathlib.Path(args.out)) if args.out else default_out(args.run_dirs)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(table(runs))
    curves = {
        run.label: (
            (run.env_steps, run.update_seconds, run.success, run.returns),
            (run.eval_env_steps, run.eval_wall_seconds, run.eval_success),
        )
        for run in runs
    }
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        plots.run_comparison(curves, out, f"{args.title} ({device})")
    except OSError as error:
        print(f"error: {paths.os_error_message(error)}", file=sys.stderr)
        return 2
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
