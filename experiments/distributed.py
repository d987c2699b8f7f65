"""The command-line options that make a command one of several processes (`jax.distributed`), shared by run
and sweep: on SLURM the processes find each other alone; elsewhere `--coordinator`, `--num-processes` and
`--process-id` say how."""

import argparse

import jax


def add_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """Adds `--distributed` and the three options that go with it; `what` names the folder every process shares."""
    parser.add_argument(
        "--distributed",
        action="store_true",
        help="one of several processes (several hosts, or one process per GPU): run the same command in each, "
        f"with the same {what}; on SLURM the processes find each other alone, elsewhere give the options below",
    )
    parser.add_argument("--coordinator", metavar="HOST:PORT", help="with --distributed: process 0's address")
    parser.add_argument("--num-processes", type=int, help="with --distributed: how many processes in all")
    parser.add_argument("--process-id", type=int, help="with --distributed: this process's index, from 0")


def check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Exits with the usage where the joining options come without `--distributed`."""
    joining = (args.coordinator, args.num_processes, args.process_id)
    if any(option is not None for option in joining) and not args.distributed:
        parser.error("--coordinator, --num-processes and --process-id go with --distributed")


def join(args: argparse.Namespace) -> None:
    """Joins the other processes (`jax.distributed.initialize`); ValueError in one line where that fails."""
    try:
        jax.distributed.initialize(
            coordinator_address=args.coordinator, num_processes=args.num_processes, process_id=args.process_id
        )
    except (ValueError, RuntimeError) as error:
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise ValueError(
            f"--distributed could not join the other processes ({first_line}); outside SLURM give --coordinator "
            "HOST:PORT, --num-processes N and --process-id I"
        ) from None
