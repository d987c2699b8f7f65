"""Where a run's metric rows go besides metrics.jsonl: TensorBoard (always) and Weights & Biases (when asked).

A sink takes each row (a flat dict of floats with "updates" and "env_steps") and draws it against env steps,
the x-axis every learner and batch size shares. wandb is an optional extra (`pip install jaxarm[wandb]`),
imported only when a run asks for it; offline mode is wandb's own (`WANDB_MODE=offline`, or `offline=True`).
"""

import contextlib
import dataclasses
import hashlib
import importlib
import importlib.abc
import pathlib
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any, Protocol


class Sink(Protocol):
    def write(self, row: dict[str, float]) -> None: ...

    def close(self) -> None: ...


def summary_writer_class() -> type:
    """tensorboardX's SummaryWriter. tensorboardX imports torch wherever it is installed, only to accept torch
    tensors (the rows hold floats): its import took 2.7-3.8 s of a run's start on an H200 host with torch (sampled,
    2026-11-27; without torch, 0.03-0.1 s on the 2-core CPU), while the run's other processes waited. Where torch is
    not imported yet, it is hidden from this thread while tensorboardX imports (`hidden_from_this_thread`)."""
    if "torch" in sys.modules:
        from tensorboardX import SummaryWriter
    else:
        with hidden_from_this_thread("torch"):
            from tensorboardX import SummaryWriter
    return SummaryWriter


class _HiddenFromThread(importlib.abc.MetaPathFinder):
    """A finder under which `import NAME` fails in one thread (ModuleNotFoundError) and is left to the other
    finders in every other thread."""

    def __init__(self, name: str, thread: int):
        self.name, self.thread = name, thread

    def find_spec(self, fullname, path, target=None):
        if fullname == self.name and threading.get_ident() == self.thread:
            raise ModuleNotFoundError(f"{fullname} is hidden while tensorboardX imports", name=fullname)
        return None


@contextlib.contextmanager
def hidden_from_this_thread(name: str) -> Iterator[None]:
    """Within the block, `import NAME` fails in this thread alone. Not by `sys.modules[NAME] = None`, which every
    thread sees: the run's compile thread runs meanwhile, and code there may import NAME or find a None in its
    place. `sys.meta_path` is replaced, never changed in place, so that a thread going through its finders as this
    one installs or removes its own sees one list throughout."""
    finder = _HiddenFromThread(name, threading.get_ident())
    sys.meta_path = [finder, *sys.meta_path]
    try:
        yield
    finally:
        sys.meta_path = [other for other in sys.meta_path if other is not finder]


class TensorBoardSink:
    """Event files under `directory`, each metric against env steps; with `purge_step`, TensorBoard hides the
    events of earlier writers at that env step and beyond (those a killed run logged past its last checkpoint)."""

    def __init__(self, directory: pathlib.Path, purge_step: int | None = None):
        # tensorboardX names its file by the second and the host alone and opens it with "wb": a resume in the
        # same second as the writer before it (one process, a kill and a resume) wrote over that one's events
        # (2-core CI, 1 run). The nanosecond suffix keeps both and sorts the later after, the order in which
        # TensorBoard reads them, so that its purge hides the earlier events past `purge_step`.
        self.writer = summary_writer_class()(
            str(directory), purge_step=purge_step, filename_suffix=f".{time.time_ns()}"
        )

    def write(self, row: dict[str, float]) -> None:
        for name, value in row.items():
            self.writer.add_scalar(name, value, int(row["env_steps"]))

    def close(self) -> None:
        try:
            self.writer.close()
        except OSError:
            # A full disk: tensorboardX would try again at exit and print tracebacks (its atexit hook, then its
            # writing thread) after the run's own one-line error. Its last events are lost either way.
            for file_writer in (self.writer.all_writers or {}).values():
                events = file_writer.event_writer
                if events._worker is not None and events._worker.is_alive():
                    events._worker.stop()
                events._closed = True
            raise


@dataclasses.dataclass(frozen=True)
class WandbOptions:
    """A wandb run to log to: its project, and offline (files under the run directory, synced later)."""

    project: str
    offline: bool = False


def wandb_run_id(name: str, first_start: dict[str, Any]) -> str:
    """The wandb run id of the run directory `name` whose training first started as `first_start` records (its
    provenance record): the name and 8 hex digits of that start's host, time and command. wandb merges the runs of
    one id in a project, so the name alone made two runs called `mine` one; a resumed run keeps its first start,
    and so its id. (Each try of a gated run after the first adds `try_suffix` to its name and id.)"""
    started = f"{first_start['hostname']} {first_start['time']} {first_start['command']}"
    return f"{name}-{hashlib.sha256(started.encode()).hexdigest()[:8]}"


def try_suffix(try_index: int) -> str:
    """What the wandb name and id of a gated run's try add (`RunConfig.retry_below`): nothing for the first, `-tryK`
    for the K-th after it. A try starts again from env step 0, which wandb drops within one run."""
    return f"-try{try_index + 1}" if try_index else ""


class WandbSink:
    """One wandb run per run directory, or per try of a gated run (named as it, with the id `wandb_run_id`: resumed
    runs continue it), each metric against env steps."""

    def __init__(self, options: WandbOptions, run_dir: pathlib.Path, config: dict[str, Any], run_id: str, name: str):
        try:
            wandb = importlib.import_module("wandb")
        except ImportError:
            raise ValueError("logging to wandb needs the wandb package: pip install 'jaxarm[wandb]'") from None
        self.run = wandb.init(
            project=options.project,
            name=name,
            id=run_id,
            resume="allow",
            dir=str(run_dir),
            config=config,
            mode="offline" if options.offline else None,
        )

    def write(self, row: dict[str, float]) -> None:
        self.run.log(row, step=int(row["env_steps"]))

    def close(self) -> None:
        self.run.finish()
