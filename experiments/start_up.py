"""How a command of experiments starts and ends. Ctrl-C while it starts: `python -m experiments.X` calls
`exit_on_ctrl_c()` before its heavy imports, and its `main` puts Python's own handler back once start-up is over.
Its output's reader gone: `exit_with(main)` ends it quietly. Imports nothing heavy, so that it runs first."""

import os
import signal
import sys
from collections.abc import Callable
from typing import NoReturn

from jaxarm.exits import OUTPUT_CLOSED, STOPPED_BY_SIGNAL


def _exit_during_start_up(signum, frame):
    print("\ninterrupted while starting: nothing was written", file=sys.stderr, flush=True)
    os._exit(STOPPED_BY_SIGNAL)


def exit_on_ctrl_c() -> None:
    """Makes Ctrl-C end the process at once, saying that nothing was written: a KeyboardInterrupt raised inside
    the imports of JAX and its libraries can be swallowed by a library's broad `except` (a run then trained to the
    end in 4 of 15 Ctrl-C during start-up)."""
    signal.signal(signal.SIGINT, _exit_during_start_up)


def exit_with(main: Callable[[], int]) -> NoReturn:
    """Exits with `main()`'s status, or quietly with OUTPUT_CLOSED where the reader of the output went away
    (`... | head -1`), as other commands end then: Python printed a BrokenPipeError traceback, and another as it
    flushed the output at exit. What the command wrote before it printed is kept."""
    try:
        code = main()
        if sys.stdout is not None:  # None where the command started with its output closed
            sys.stdout.flush()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so that the flush at exit finds a reader
        code = OUTPUT_CLOSED
    sys.exit(code)
