"""Benchmarks: `python -m experiments.bench SUITE [options]` (SUITE: arm2d, panda_sort, ...).

Each suite prints ratios against a peer measured in the same run, with the device named.
"""

import importlib
import sys

SUITES = ("arm2d", "panda_sort", "training", "scaling", "ceilings", "profile", "camera")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] not in SUITES:
        print(
            f"usage: python -m experiments.bench {{{','.join(SUITES)}}} [options]  (--help after a suite)",
            file=sys.stderr,
        )
        return 2
    importlib.import_module(f"experiments.benchmarks.{argv[0]}").main(argv[1:])
    return 0


if __name__ == "__main__":
    sys.exit(main())
