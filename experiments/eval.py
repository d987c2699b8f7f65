"""Evaluate a saved run: `python -m experiments.eval RUN_DIR [--episodes N] [--seed S] [--video gif|mp4]
[--perturb NAME=V1,V2 ...]`.

Loads the run's config and the policy of its latest checkpoint (or of the best one from evaluation during training,
`--best`; the envs' state and any replay are not read), runs the deterministic policy on N fresh episodes, prints the
result and writes it to its own file, eval-<episodes>-<seed>-<update>.json (eval-<episodes>-<seed>-best.json with
--best; training's eval.json is kept).
With --video it writes video.gif or video.mp4 of a few episodes drawn without a window. With --perturb it evaluates
the policy under changes of the eval env's params instead: NAME=V1,V2 changes one param to each value in turn (all
values in one compiled program), NAME=V+NAME=V changes several together; --randomized-ends adds each param the run
randomises at both ends of its range, and --worst-corner (which implies it) then every such param at once at the end
that hurt the policy more. Beside the nominal params, it writes a robustness table and plot
(robustness-<episodes>-<seed>-<update|best>-<digest of the perturbations>.json, .md and .png).
The run directory is locked while this writes.

A video asked for where the run's env cannot draw (no GL platform) fails first: the presets, learners and runner
are imported only after that check. Importing them first made a Panda run's failure take 5.5 s on the idle 2-core
CPU and 15-28 s on the busy one; what remains is importing jax and the env's module (mujoco.mjx).
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c(start_up.AT_ONCE)  # first: Ctrl-C ends it at once, from its first import on

import argparse
import json
import os
import pathlib
import time

from jaxarm import headless

VIDEO_EPISODES = 3


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.eval", description=__doc__)
    parser.add_argument("run_dir")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument(
        "--video",
        nargs="?",
        const="gif",
        choices=headless.FORMATS,
        help=f"also write video.gif (default) or video.mp4 of {VIDEO_EPISODES} episodes",
    )
    parser.add_argument(
        "--best", action="store_true", help="evaluate the best checkpoint (best/) instead of the latest"
    )
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument(
        "--perturb",
        nargs="+",
        metavar="NAME=V1,V2",
        default=[],
        help="evaluate under each value of each env param (e.g. finger_friction=0.8,1.5 mass_scale=0.5,3), or "
        "under several changed together (e.g. finger_friction=1.0+mass_scale=2)",
    )
    parser.add_argument(
        "--randomized-ends",
        action="store_true",
        help="also evaluate each env param the run randomises at both ends of its range",
    )
    parser.add_argument(
        "--worst-corner",
        action="store_true",
        help="with --randomized-ends (implied): then every randomised param at once, each at the end of its range "
        "where it alone placed less (ties: the lower return)",
    )
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    began = time.perf_counter()
    run_dir = pathlib.Path(args.run_dir)
    try:
        ends_flag = "--worst-corner" if args.worst_corner else "--randomized-ends" if args.randomized_ends else None
        problem = (gl_problem(run_dir) if args.video else None) or (
            ends_problem(run_dir, ends_flag) if ends_flag else None
        )
        if problem is None:
            return evaluate_run(run_dir, args, began)
    except headless.GLImportError as error:  # a MUJOCO_GL that mujoco cannot load, met where mujoco is imported
        problem = str(error)
    print(f"error: {problem}", file=sys.stderr)
    return 2


def saved_config(run_dir: pathlib.Path) -> dict | None:
    """The run's config.json as saved, read without importing the learners; None where it cannot be read (for
    `evaluate_run` to report)."""
    try:
        saved = json.loads((run_dir / "config.json").read_text())
    except (OSError, ValueError):
        return None
    return saved if isinstance(saved, dict) else None


def ends_problem(run_dir: pathlib.Path, flag: str) -> str | None:
    """Why `flag` (--randomized-ends or --worst-corner) has nothing to evaluate in the run in `run_dir` (it
    randomises no env param), found before the seconds of imports an evaluation takes; None where it has, or the
    config is for `evaluate_run`."""
    saved = saved_config(run_dir)
    if saved is None or saved.get("randomize"):
        return None
    return f"{flag}: the run randomises no env param"


def gl_problem(run_dir: pathlib.Path) -> str | None:
    """Why the env of the run in `run_dir` cannot draw here (`headless.gl_problem`); None where it draws without
    OpenGL or GL works. Imports the env's class alone. A directory without a readable run is for
    `evaluate_run` to report."""
    from jaxarm.envs import registry

    saved = saved_config(run_dir)
    try:
        draws_with_gl = registry.draws_with_gl(saved["env"]) if saved else False
    except (ValueError, KeyError, TypeError):
        return None
    return headless.gl_problem() if draws_with_gl else None


def reserve_gpu_memory_on_demand(environ=os.environ) -> None:
    """Has JAX take a GPU's memory as the evaluation needs it, where the user has not chosen, so that an evaluation
    runs beside a training on the same GPU. Reserving three quarters of an H200 up front (JAX's default, which
    training keeps) took 1.5 s at the first transfer; the evaluation's own allocations take part of that back.
    Call it before JAX starts its backend."""
    environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")


def evaluate_run(run_dir: pathlib.Path, args: argparse.Namespace, began: float) -> int:
    """Evaluates (or draws, or perturbs) the run as `args` ask, prints and writes the results; the exit status."""
    reserve_gpu_memory_on_demand()
    import jax

    from jaxarm import ranges
    from jaxarm.agents.common import checkpoint
    from jaxarm.runner import learners, paths, progress, rundir, video
    from jaxarm.runner.cache import enable_compilation_cache

    phases = {"imports": time.perf_counter() - began}
    try:
        ranges.check_value("--episodes", args.episodes, int, ranges.AT_ONCE)
        ranges.check_value("--seed", args.seed, int, ranges.SEED)
        enable_compilation_cache()
        clock = time.perf_counter()
        jax.devices()  # starts the backend: its time apart from the env's
        phases["devices"] = time.perf_counter() - clock
        clock = time.perf_counter()
        config, _ = rundir.read_config(run_dir)  # validating the config builds the env, which the trainer reuses
        trainer = learners.make_trainer(config, run_dir)
        phases["env"] = time.perf_counter() - clock
        progress.explain_slow_compiles(config.make_env(randomized=False)[0])  # the env the trainer built
        progress.explain_gspmd(len(jax.devices()))  # evaluate_state spreads its episodes as training does
        with rundir.locked(run_dir):
            clock = time.perf_counter()
            state = learners.restore_state(run_dir, trainer, config, best=args.best, acting=True)
            phases["checkpoint"] = time.perf_counter() - clock
            if args.perturb or args.randomized_ends or args.worst_corner:
                write_robustness(run_dir, config, trainer, state, args)
                return 0
            start = time.perf_counter()
            result = learners.evaluate_state(trainer, config, state, args.episodes, args.seed)
            result["checkpoint_update"] = int(state.updates)
            path = rundir.eval_path(run_dir, args.episodes, args.seed, checkpoint_name(state, args.best))
            rundir.write_json(path, result)  # before it is printed: an output closed early (`| head`) loses nothing
            print(
                f"{run_dir}: success_rate {result['success_rate']:.3f} return_mean {result['return_mean']:.2f} "
                f"over {result['episodes']} episodes (update {result['checkpoint_update']}; "
                f"{time.perf_counter() - start:.1f} s with compilation, after {start - began:.1f} s of devices, "
                f"env and checkpoint: {', '.join(f'{name} {seconds:.1f} s' for name, seconds in phases.items())})",
                flush=True,
            )
            print(f"wrote {path}")
            if args.video:
                env, env_params = config.make_eval_env()
                key = jax.random.PRNGKey(args.seed + 1)
                start = time.perf_counter()
                frames = video.episode_frames(env, env_params, trainer, state, key, VIDEO_EPISODES)
                video_path = run_dir / f"video.{args.video}"
                video.write_video(video_path, frames)
                print(f"wrote {video_path} ({len(frames)} frames, {time.perf_counter() - start:.1f} s)")
    except (ValueError, OSError, checkpoint.CheckpointError, video.RenderError) as error:
        print(f"error: {paths.os_error_message(error) if isinstance(error, OSError) else error}", file=sys.stderr)
        # Imported here: experiments.run brings every preset and the training loop, 0.5-1 s an evaluation needs not.
        from experiments.run import quiet_libraries

        quiet_libraries()
        return 2
    return 0


def checkpoint_name(state, best: bool) -> str:
    """How the files of an evaluation name the checkpoint evaluated: "best", or the latest's update count."""
    return "best" if best else str(int(state.updates))


def write_robustness(run_dir: pathlib.Path, config, trainer, state, args) -> None:
    """Evaluates `state` under `args.perturb`, `args.randomized_ends` and `args.worst_corner`, prints the table and
    writes it with its rows and plot."""
    import jax

    from jaxarm.runner import robustness, rundir

    env, env_params = config.make_eval_env()
    ends: dict[str, list[float]] = {}
    if args.randomized_ends or args.worst_corner:  # a run that randomises nothing was refused before (ends_problem)
        ends = robustness.range_ends(dict(config.randomize), env_params)
    perturbations = dict(ends)
    try:  # the library's words for a perturbation it refuses, under the flag that asked for it
        combined = [robustness.parse_combined(text) for text in args.perturb if "+" in text]
        for text in args.perturb:
            if "+" not in text:
                name, values = robustness.parse_perturbation(text)
                perturbations[name] = [*perturbations.get(name, []), *values]
        key = jax.random.PRNGKey(args.seed)
        start = time.perf_counter()
        rows = robustness.evaluate_perturbations(
            env, env_params, trainer.act, state, key, args.episodes, perturbations, combined
        )
        if args.worst_corner:
            corner = robustness.worst_corner(rows, ends)
            (row,) = robustness.evaluate_perturbations(
                env, env_params, trainer.act, state, key, args.episodes, {}, [corner], with_nominal=False
            )
            rows.append({**row, "param": f"{robustness.WORST_CORNER}: {row['param']}"})
    except robustness.PerturbationError as error:
        raise ValueError(f"--perturb: {error}") from None
    text = robustness.table(rows)
    print(f"{text}\n({args.episodes} episodes a row, {time.perf_counter() - start:.1f} s with compilation)")
    flags = {"--randomized-ends": args.randomized_ends, "--worst-corner": args.worst_corner}
    request = [*args.perturb, *(flag for flag, asked in flags.items() if asked)]
    checkpoint = checkpoint_name(state, args.best)
    stem = rundir.robustness_stem(run_dir, args.episodes, args.seed, checkpoint, request)
    device = jax.devices()[0].device_kind
    record = {"device": device, "perturb": request, "episodes": args.episodes, "checkpoint": checkpoint, "rows": rows}
    rundir.write_json(stem.with_suffix(".json"), record)
    stem.with_suffix(".md").write_text(text + "\n")
    robustness.plot(rows, stem.with_suffix(".png"), f"{run_dir.name}: robustness")
    print(f"wrote {stem}.json, .md and .png")


if __name__ == "__main__":
    start_up.exit_with(main)
