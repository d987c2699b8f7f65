"""Train a named config: `python -m experiments.run --config NAME [key=value ...]`.

A thin CLI over the library loop `jaxarm.runner` (chunks of compiled updates; between them metrics, progress,
NaN stop, evaluation and checkpoints of the whole learner state). `--resume RUN_DIR [key=value ...]` continues
from the latest checkpoint, bit-identical to an uninterrupted run on CPU; it may extend the budget or change
evaluation and checkpoint cadence. Ctrl-C or SIGTERM checkpoints at the next chunk end. `--show` lists every
config field and env param with its default and meaning. On a host of several GPUs a PPO run on MJX Warp starts one
process per GPU by itself (`--local-processes 1` keeps one process); `num_envs` is the total over all of them.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c()  # first: nothing is written before main()

import argparse
import logging
import math
import pathlib
import re
import traceback

import jax

from experiments import configs, distributed
from jaxarm.agents import registry
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig, apply_overrides
from jaxarm.envs.panda.mjx_impl import warp_available
from jaxarm.exits import STOPPED_BY_SIGNAL
from jaxarm.runner import loop, paths, processes, resumes, rundir, show, signals
from jaxarm.runner.cache import enable_compilation_cache
from jaxarm.runner.sinks import WandbOptions
from jaxarm.unraisable import drop_unraisable


def minutes(text: str) -> float:
    """`--stop-after-minutes`: a finite number of minutes, 0 or more (0: stop after the first chunk)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number of minutes, 0 or more, got {text!r}")
    return value


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog="python -m experiments.run",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Presets: "
        + ", ".join(configs.names())
        + ". Compilations are cached on disk: see jaxarm/runner/cache.py.",
    )
    parser.add_argument("--config", help="preset name (see --list)")
    parser.add_argument("--list", action="store_true", help="list presets and exit")
    parser.add_argument(
        "--show", action="store_true", help="print the config's fields and its env's params (with overrides) and exit"
    )
    parser.add_argument(
        "--out", type=paths.given, help="run directory (default runs/<config>-<timestamp>, made unique)"
    )
    parser.add_argument(
        "--resume",
        metavar="RUN_DIR",
        help="continue the run in this directory from its latest checkpoint; overrides may change "
        + ", ".join(resumes.RESUMABLE_KEYS)
        + " and eval_env_params.NAME",
    )
    parser.add_argument(
        "--stop-after-minutes",
        type=minutes,
        help="checkpoint and stop after the chunk that passes this wall time since the run started, its stages and "
        "compilations included (resume later)",
    )
    parser.add_argument("--wandb", metavar="PROJECT", help="also log to this Weights & Biases project")
    parser.add_argument(
        "--wandb-offline", action="store_true", help="with --wandb: write under the run directory, sync later"
    )
    distributed.add_arguments(parser, "--out")
    parser.add_argument("overrides", nargs="*", help="config overrides key=value (env_params.NAME=VALUE too)")
    args = parser.parse_args(argv)
    if not (args.list or args.config or args.resume):
        parser.error("give --config NAME, --resume RUN_DIR or --list")
    if args.resume and args.config:
        parser.error("--resume takes the config saved in the run directory; give no --config")
    if args.resume and args.out:  # else --out was left aside without a word
        parser.error("--resume continues the run in its own directory; give no --out")
    if (args.wandb is not None and not args.wandb.strip()) or (args.wandb_offline and args.wandb is None):
        parser.error("--wandb takes a project's name, and --wandb-offline goes with it")  # else left aside too
    distributed.check_arguments(parser, args)
    if args.distributed and args.config and not args.out and not (args.list or args.show):
        parser.error("with --distributed give --out: every process writes to one run directory")
    return args


def quiet_libraries() -> None:
    """After an error was reported, silences what libraries log while shutting down (orbax's asyncio threads
    print "Event loop is closed" tracebacks by the hundred)."""
    for name in ("asyncio", "absl", "orbax", "jax"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def program_error_cause(error: BaseException) -> str:
    """What raised inside a compiled program, from JAX's runtime error: its last line (an env's host check, MJX
    Warp's kernel launch) without XLA's status and the program's name."""
    lines = str(error).strip().splitlines() or [type(error).__name__]
    cause = re.sub(r"\s*\[executable_name='[^']*'\]$", "", lines[-1])
    return re.sub(r"^[A-Z_]+: (FFI callback error: )?", "", cause)


def said_once(error: BaseException) -> None:
    """Keeps `error`, reported, from being printed again at exit: JAX's exit handlers wait on the failed program's
    effects and raise it again, with a traceback each (twice, Warp on an H200)."""
    cause = program_error_cause(error)
    drop_unraisable(lambda again: type(again) is type(error) and program_error_cause(again) == cause)


def resume_command(run_dir) -> str:
    """The command that continues the run in `run_dir`."""
    return f"python -m experiments.run --resume {run_dir}"


def cli_message(error: BaseException) -> str:
    """`error`'s message, with this CLI's command where the library marked the error as one a resume gets past
    (`rundir.resumable`)."""
    resume_dir = getattr(error, "resume_dir", None)
    if resume_dir is None:
        return str(error)
    return f"{error}; continue with: {resume_command(resume_dir)}"


def planned_config(args: argparse.Namespace) -> RunConfig:
    """The run's config (`--resume`'s saved one, or the preset with its overrides), not validated: validating
    builds the env, which starts JAX's backend, and JAX takes most of every GPU's memory at start, which a
    process that may only start others must leave to them."""
    if args.resume:
        return rundir.read_config(pathlib.Path(args.resume), validate=False)[0]
    return apply_overrides(configs.get(args.config, validate=False), args.overrides, validate=False)


def spreads_over_gpus(config: RunConfig) -> bool:
    """Whether a run of `config` starts one process per GPU by itself: one on MJX Warp, of a learner measured so
    (`registry.Learner.one_process_per_gpu`: PPO), without a teacher (BENCHMARKS.md#devices); TD3 and distillation
    have not run as several processes, so they take several only where `--local-processes` asks."""
    measured = registry.learner_for(config).one_process_per_gpu and not registry.teacher_of(config)
    return measured and distributed.steps_on_warp(dict(config.env_kwargs), warp_available())


def local_processes(args: argparse.Namespace) -> int:
    """How many processes of this run to start on this host (`distributed.local_process_count`)."""
    if args.local_processes is not None or args.distributed:
        # Told, or one of several already: no config to read, no GPUs to count (in each of the processes).
        return distributed.local_process_count(args.local_processes, args.distributed, False, 0)
    spreads = spreads_over_gpus(planned_config(args))
    return distributed.local_process_count(None, False, spreads, distributed.gpus_here() if spreads else 0)


def start_local_processes(args: argparse.Namespace, argv: list[str], count: int) -> int:
    """Runs this command as `count` processes of one run on this host (`distributed.spawn`), all given the run
    directory they share: `--out`, or one named and made here as a run of one process would make it."""
    if args.out:
        paths.check_output_dir(pathlib.Path(args.out), "--out")  # here once, not in every process
    run_dir = args.resume or args.out
    if run_dir is None:
        run_dir = str(rundir.new_run_dir(args.config))
        argv = ["--out", run_dir, *argv]
    if args.local_processes is None:
        print(
            f"{run_dir}: MJX Warp on {count} GPUs, one process each (faster than one process driving them all; "
            "--local-processes 1 for that)",
            flush=True,
        )
    return distributed.spawn(main, argv, count, resume_command(run_dir))


def shown_config(args: argparse.Namespace) -> tuple[RunConfig, str]:
    """(config, preset) that `--show` describes: `--resume`'s with its overrides, or the preset with its own."""
    if args.resume:
        config, preset = rundir.read_config(pathlib.Path(args.resume))
        return resumes.apply_resume_overrides(config, args.overrides), preset
    return apply_overrides(configs.get(args.config), args.overrides), args.config


def train_or_resume(args: argparse.Namespace, options: loop.Options) -> tuple[pathlib.Path, dict]:
    """(run directory, final evaluation) of the run `--resume` continues, or of a new one of `--config`."""
    if args.resume:
        run_dir = pathlib.Path(args.resume)
        result, _ = loop.resume(run_dir, args.overrides, options)
        return run_dir, result
    preset = args.config
    config = apply_overrides(configs.get(preset), args.overrides)
    if args.out:
        paths.check_output_dir(pathlib.Path(args.out), "--out")
    run_dir = pathlib.Path(args.out) if args.out else rundir.new_run_dir(preset)
    return run_dir, loop.train(config, run_dir, preset=preset, options=options)


def take_over_interrupts() -> None:
    """Start-up is over for a command that trains (run, sweep): from here Ctrl-C (and SIGTERM) raise
    KeyboardInterrupt, which its `main` reports in one line, and are remembered for the chunk loop, which
    checkpoints on them, in case a library swallows the KeyboardInterrupt (`signals.remember_interrupts`)."""
    start_up.start_up_over()
    signals.remember_interrupts()


def main(argv=None) -> int:
    take_over_interrupts()
    try:
        return _main(sys.argv[1:] if argv is None else argv)
    except KeyboardInterrupt:
        # A process its launcher stopped for a peer's failure says so (the launcher's line says which, and how to
        # go on): a SIGTERM that came outside the chunk loop, as a checkpoint was written, read as a Ctrl-C.
        why = "another process of the job has gone; " if distributed.stopped_for_a_failed_peer() else ""
        print(f"\ninterrupted: {why}checkpoints saved so far are kept", file=sys.stderr)
        quiet_libraries()
        return STOPPED_BY_SIGNAL


def _main(argv) -> int:
    args = parse_args(argv)
    if args.list:
        for name, description in configs.describe().items():
            print(f"{name:24s} {description}")
        return 0
    options = loop.Options(
        stop_after_s=None if args.stop_after_minutes is None else 60 * args.stop_after_minutes,
        wandb=WandbOptions(args.wandb, offline=args.wandb_offline) if args.wandb else None,
        presets=configs.get,
    )
    try:
        if args.show:
            print(show.describe(*shown_config(args)))
            return 0
        count = local_processes(args)
        if count > 1:
            return start_local_processes(args, list(argv), count)
        if args.distributed:
            distributed.join(args)
        enable_compilation_cache()
        run_dir, result = train_or_resume(args, options)
    except (ValueError, checkpoint.CheckpointError, loop.TrainingDiverged) as error:
        distributed.ignore_stop_signals_in_a_job(args)
        distributed.leave_if_peers_lost(error, resume_command(args.resume or args.out))  # a checkpoint's, say
        print(f"error: {cli_message(error)}", file=sys.stderr)
        quiet_libraries()
        return 2
    except OSError as error:
        distributed.ignore_stop_signals_in_a_job(args)
        print(f"error: {paths.os_error_message(error, args.resume or args.out)}", file=sys.stderr)
        quiet_libraries()
        return 2
    except loop.TrainingInterrupted as error:
        distributed.ignore_stop_signals_in_a_job(args)
        print(cli_message(error), file=sys.stderr)
        quiet_libraries()
        return STOPPED_BY_SIGNAL
    except jax.errors.JaxRuntimeError as error:  # a collective's, where a peer has gone; else the program's
        distributed.ignore_stop_signals_in_a_job(args)
        distributed.leave_if_peers_lost(error, resume_command(args.resume or args.out))
        resume_dir = getattr(error, "resume_dir", None)
        if resume_dir is None:
            raise
        traceback.print_exc()  # whole, for a report: a host check's own traceback is in it
        print(
            f"error: training failed on the device: {program_error_cause(error)}; checkpoints saved so far are kept; "
            f"continue with: {resume_command(resume_dir)}",
            file=sys.stderr,
        )
        said_once(error)
        quiet_libraries()
        return 1
    if not processes.is_primary():
        return 0
    print(
        f"{run_dir}: success_rate {result['success_rate']:.3f}, return_mean {result['return_mean']:.2f}, "
        f"{result['env_steps']:,} env steps in {result['train_wall_time']:.1f} s on {result['device']}"
    )
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
