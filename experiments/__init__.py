"""Command-line entry points: run, eval, bench, sweep."""

import sys

if sys.argv[0] == "-m":  # `python -m experiments.X` while Python locates X: the first of our lines it runs
    from experiments import start_up

    start_up.exit_on_ctrl_c()
