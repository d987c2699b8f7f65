"""Ctrl-C, SIGTERM and SIGHUP during training: a request to stop at the next chunk end (the chunk loop, chunks.py,
checks it), or, asked twice, an end at once. Nothing here checkpoints or decides when a chunk ends."""

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

from jaxarm.exits import STOPPED_BY_SIGNAL

_asked_before_the_loop = threading.Event()
"""Set by `raise_and_remember`: a Ctrl-C or SIGTERM came before a chunk loop installed its `StopRequests`."""


def raise_and_remember(signum, frame):
    """The handler of Ctrl-C and SIGTERM from a run's start to its chunk loop: raises KeyboardInterrupt, as Python's
    own handler does for Ctrl-C, and remembers the request. A library may swallow the KeyboardInterrupt (JAX's
    garbage-collection callback while XLA compiled: the run trained to its end, rc 0); the next `StopRequests` then
    starts requested, and the run stops at its first chunk end with a checkpoint."""
    _asked_before_the_loop.set()
    raise KeyboardInterrupt


def remember_interrupts() -> None:
    """Installs `raise_and_remember` for Ctrl-C, and for SIGTERM where nothing else handles it (a process of
    several has its own handler: experiments.distributed). Main thread only."""
    signal.signal(signal.SIGINT, raise_and_remember)
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, raise_and_remember)


STOPPING = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that ask a chunk loop to stop (`StopRequests`)."""


class StopRequests:
    """Ctrl-C (SIGINT), SIGTERM and SIGHUP, while installed, ask the loop to stop at the next chunk end; a second
    Ctrl-C ends the process at once (STOPPED_BY_SIGNAL), keeping the checkpoints saved so far. Installed only in the
    main thread (signals cannot be caught elsewhere). `aborted` ends the line said then (e.g. how to resume)."""

    def __init__(self, aborted: str = ""):
        self.requested = _asked_before_the_loop.is_set()
        self.aborted = aborted
        if self.requested:  # its KeyboardInterrupt was swallowed (`raise_and_remember`)
            _asked_before_the_loop.clear()
            print("\nasked to stop before training began: stopping at the first chunk end", file=sys.stderr, flush=True)

    def _handle(self, signum, frame):
        if self.requested and signum == signal.SIGINT:
            print(
                f"\nSIGINT again: aborted; the checkpoints saved before are kept{self.aborted}",
                file=sys.stderr,
                flush=True,
            )
            # Not KeyboardInterrupt: unwinding while XLA compiles or runs on other threads printed a traceback
            # (rc -2, 3 of 3 tries during compilation) or segfaulted at interpreter exit (rc -11), and nothing is
            # left to clean up that a resume does not (rows past the last checkpoint dropped, TensorBoard's purged).
            os._exit(STOPPED_BY_SIGNAL)
        if signum == signal.SIGHUP:
            output_to_nowhere()
        self.requested = True
        print(
            f"\n{signal.Signals(signum).name}: stopping at the next chunk end with a checkpoint "
            "(Ctrl-C again to abort now)",
            file=sys.stderr,
            flush=True,
        )

    @contextlib.contextmanager
    def installed(self) -> Iterator["StopRequests"]:
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        # A SIGHUP ignored (`nohup`) stays ignored: the run was asked to outlive its terminal.
        ignored = signal.SIGHUP if signal.getsignal(signal.SIGHUP) is signal.SIG_IGN else None
        asking = [signum for signum in STOPPING if signum != ignored]
        previous = {signum: signal.signal(signum, self._handle) for signum in asking}
        try:
            yield self
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)


def output_to_nowhere() -> None:
    """Points this process's stdout and stderr (its file descriptors, which XLA's C++ logs share) at the null device.
    A SIGHUP says the terminal has closed, where a line written would fail (EIO): the run stops at its chunk end with
    a checkpoint, unheard, and its files say what it did."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # buffered text for the closed terminal is dropped
            stream.flush()
    nowhere = os.open(os.devnull, os.O_WRONLY)
    for descriptor in (1, 2):
        os.dup2(nowhere, descriptor)
    os.close(nowhere)
