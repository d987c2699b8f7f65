"""Command-line entry points: run, eval, bench, sweep."""
