"""How a command of experiments starts and ends. Ctrl-C while it starts: `python -m experiments.X` calls
`exit_on_ctrl_c()` before its heavy imports, and the `main` of a command that trains puts Python's own handler back
once start-up is over. Its output's reader gone: `exit_with(main)` ends it quietly. Imports nothing heavy, so that
it runs first."""

import os
import signal
import sys
from collections.abc import Callable


def ended_by(signum: int) -> int:
    """The exit status of a command that `signum` ended, as a shell reports one a signal killed: 128 + its number,
    the rule `jaxarm.exits` declares its statuses by (STOPPED_BY_SIGNAL for SIGINT). Not imported from there:
    importing jaxarm takes ~40 ms (importlib.metadata), which doubled the window at the start in which Ctrl-C gave
    a traceback, and importing it from a handler amid another import failed ("partially initialized module")."""
    return 128 + signum


_before: dict = {}
"""The handlers `exit_on_ctrl_c` replaced, by signal, and its own ("handler"): `start_up_over` puts them back."""

_cleanups: list[Callable[[], None]] = []
"""What `exit_on_ctrl_c`'s handler does before the process ends, newest first (`CleanedOnCtrlC`)."""

WHILE_STARTING = "while starting: nothing was written"
"""What Ctrl-C during the start-up of a command that trains says: its `main` takes Ctrl-C over from there."""
AT_ONCE = "and ended at once; run the command again for its results"
"""What Ctrl-C says at any moment of a command that trains nothing (eval, export, compare, transfer, rehearse,
bench), which keeps `exit_on_ctrl_c` all along: a KeyboardInterrupt within it ended in tracebacks of up to 158
lines, in a segfault once, or was swallowed (an evaluation went on to the end, rc 0)."""


def exit_on_ctrl_c(said: str = WHILE_STARTING) -> None:
    """Makes Ctrl-C and SIGTERM end the process at once with 130 (`ended_by` SIGINT, as the commands' own handlers
    take both), saying "interrupted" and `said`: a KeyboardInterrupt raised inside the imports of JAX and its
    libraries can be swallowed by a library's broad `except` (a run then trained to the end in 4 of 15 Ctrl-C
    during start-up), and SIGTERM (a cluster's time limit, `timeout`) ended a command in its start-up without a
    word (rc -15). Called again while in force (the package installs it first, `experiments/__init__.py`), it
    changes only what is said."""
    _said[0] = said
    if signal.getsignal(signal.SIGINT) is not _exit_at_once:
        _before.update({signum: signal.signal(signum, _exit_at_once) for signum in (signal.SIGINT, signal.SIGTERM)})
        _before["handler"] = _exit_at_once


_said = [WHILE_STARTING]
"""What `_exit_at_once` says after "interrupted" (`exit_on_ctrl_c`)."""


def _exit_at_once(signum, frame):
    for each in (signal.SIGINT, signal.SIGTERM):  # a second one while the cleanups run would run them again
        signal.signal(each, signal.SIG_IGN)
    try:
        print(f"\ninterrupted {_said[0]}", file=sys.stderr, flush=True)
        for cleanup in reversed(_cleanups):
            cleanup()
    finally:  # whatever a cleanup raised: its traceback would be a second word
        os._exit(ended_by(signal.SIGINT))


class CleanedOnCtrlC:
    """While entered, Ctrl-C or SIGTERM that ends the command at once (`exit_on_ctrl_c`) calls `cleanup` first: the
    process ends by `os._exit`, which runs no `finally` and no `with` block's exit (a rehearsal stopped mid-episode
    left its temporary directory behind)."""

    def __init__(self, cleanup: Callable[[], None]):
        self.cleanup = cleanup

    def __enter__(self) -> None:
        _cleanups.append(self.cleanup)

    def __exit__(self, *exc_info) -> None:
        _cleanups.remove(self.cleanup)


def start_up_over() -> None:
    """Ends `exit_on_ctrl_c` in a command that trains, as its `main` begins: Ctrl-C raises KeyboardInterrupt again
    (the command reports it; its chunk loop checkpoints on it), and SIGTERM, where start-up's handler still has it,
    does what it did before (a process of several has its own handler by then, `distributed`)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    if _before and signal.getsignal(signal.SIGTERM) is _before["handler"]:
        signal.signal(signal.SIGTERM, _before[signal.SIGTERM])


def exit_with(main: Callable[[], int]) -> None:  # never returns: typing's NoReturn took 3 ms of start-up
    """Exits with `main()`'s status, or quietly with 141 (`ended_by` SIGPIPE) where the reader of the output went away
    (`... | head -1`), as other commands end then: Python printed a BrokenPipeError traceback, and another as it
    flushed the output at exit. What the command wrote before it printed is kept."""
    try:
        code = main()
        if sys.stdout is not None:  # None where the command started with its output closed
            sys.stdout.flush()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so that the flush at exit finds a reader
        code = ended_by(signal.SIGPIPE)
    sys.exit(code)
