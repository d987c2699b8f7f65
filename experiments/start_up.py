"""Ctrl-C while a command starts: `python -m experiments.X` calls `exit_on_ctrl_c()` before its heavy imports, and
its `main` puts Python's own handler back once start-up is over. Imports nothing heavy, so that it runs first."""

import os
import signal
import sys

from jaxarm.exits import STOPPED_BY_SIGNAL


def _exit_during_start_up(signum, frame):
    print("\ninterrupted while starting: nothing was written", file=sys.stderr, flush=True)
    os._exit(STOPPED_BY_SIGNAL)


def exit_on_ctrl_c() -> None:
    """Makes Ctrl-C end the process at once, saying that nothing was written: a KeyboardInterrupt raised inside
    the imports of JAX and its libraries can be swallowed by a library's broad `except` (a run then trained to the
    end in 4 of 15 Ctrl-C during start-up)."""
    signal.signal(signal.SIGINT, _exit_during_start_up)
