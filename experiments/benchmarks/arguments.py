"""Argument types the suites share: env counts and counts, checked against `jaxarm.ranges` as a run's config fields
are, so that a bad value ends in argparse's one-line error before anything is timed or allocated."""

import argparse

from jaxarm import ranges
from jaxarm.agents.common.config import parse_value


def env_counts(text: str) -> tuple[int, ...]:
    """`--sizes`: comma-separated env counts ("1,1024", "1e6"), each stepped at once in one program
    (`ranges.AT_ONCE`). 0 divided by zero, -8 ended in XLA's "invalid tensor dimension size" and 1e11 in int's
    "invalid literal", each a traceback after the numpy reference had been timed."""
    try:
        sizes = parse_value(text, tuple[int, ...])
        if not sizes:
            raise ValueError(f"expected comma-separated env counts, got {text!r}")
        for size in sizes:
            ranges.check_value("each env count", size, int, ranges.AT_ONCE)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return sizes


def env_count(text: str) -> int:
    """One count of envs or episodes stepped at once in one program (`ranges.AT_ONCE`, as `num_envs` and
    `eval_episodes`): `bench playground`'s --num-envs and --eval-episodes (0 divided by zero; 1e9 episodes ran out of
    memory, after a training)."""
    return _count_in(text, ranges.AT_ONCE)


def count(text: str) -> int:
    """A count of at least one that fits in int32 (`ranges.COUNT`): steps per timed scan, repeats, unroll."""
    return _count_in(text, ranges.COUNT)


def _count_in(text: str, allowed: ranges.Range) -> int:
    try:
        value = parse_value(text, int)
        ranges.check_value("the count", value, int, allowed)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return value
