"""Benchmarks: `python -m experiments.bench SUITE [options]` (`SUITE --help` lists a suite's options).

Each suite prints ratios against a peer measured in the same run, with the device named.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c(start_up.AT_ONCE)  # first: Ctrl-C ends it at once, from its first import on

import argparse
import importlib

from jaxarm.runner.cache import enable_compilation_cache

SUITES = (
    "arm2d",
    "panda_sort",
    "training",
    "scaling",
    "devices",
    "ceilings",
    "profile",
    "learner",
    "camera",
    "deploy",
    "playground",
)


def suite_summary(name: str) -> str:
    """The first line of a suite module's docstring."""
    module = importlib.import_module(f"experiments.benchmarks.{name}")
    return (module.__doc__ or "").strip().splitlines()[0]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in SUITES:
        cache = enable_compilation_cache()
        if cache:
            print(
                f"compilation cache: {cache} (a program read from it reports its load time as compile s; "
                "JAXARM_COMPILATION_CACHE=off times real compiles)",
                file=sys.stderr,
            )
        importlib.import_module(f"experiments.benchmarks.{argv[0]}").main(argv[1:])
        return 0
    parser = argparse.ArgumentParser(
        prog="python -m experiments.bench",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="suites:\n" + "\n".join(f"  {name:12s} {suite_summary(name)}" for name in SUITES),
    )
    parser.add_argument("suite", choices=SUITES)
    parser.add_argument("options", nargs=argparse.REMAINDER, help="the suite's options (SUITE --help)")
    parser.parse_args(argv)  # exits: 0 for --help, 2 with the usage for a missing or unknown suite
    return 2


if __name__ == "__main__":
    start_up.exit_with(main)
