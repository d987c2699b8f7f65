"""What the primary process writes between chunks: a row per update into metrics.jsonl and the sinks
(TensorBoard, wandb; sinks.py), and the progress bar. Nothing here runs a program or decides when a chunk ends."""

import contextlib
import json
import pathlib
import sys
from collections.abc import Iterator, Sequence

import numpy as np

from jaxarm.agents.common.trainer import Trainer
from jaxarm.runner import progress, provenance
from jaxarm.runner.sinks import Sink, TensorBoardSink, WandbOptions, WandbSink, try_suffix, wandb_run_id


def metric_rows(
    flat: dict[str, np.ndarray], first_update: int, env_steps_per_update: int, wall_time: float, steps_per_second: float
):
    """One JSON-ready row per update of a chunk: its count, env steps so far (a Python int, past int32 too), the
    chunk's wall clock and rate, and its metrics."""
    count = len(next(iter(flat.values())))
    for index in range(count):
        updates = first_update + index + 1
        row = {
            "updates": updates,
            "env_steps": updates * env_steps_per_update,
            "wall_time": wall_time,
            "steps_per_second": steps_per_second,
        }
        row.update({name: float(values[index]) for name, values in flat.items()})
        yield row


class RunLog:
    """The primary process's outputs between chunks: metrics.jsonl, the sinks (TensorBoard, wandb: a run of its own
    for each try after the first, `try_index`) and the progress bar (at `done_updates` to begin with), each closed
    with `stack`."""

    def __init__(
        self,
        stack: contextlib.ExitStack,
        run_dir: pathlib.Path,
        trainer: Trainer,
        wandb: WandbOptions | None,
        done_updates: int,
        try_index: int,
    ):
        # TensorBoard hides the events a killed run logged past the checkpoint this one resumes from.
        resumed_at = done_updates * trainer.env_steps_per_update
        purge_step = resumed_at + 1 if done_updates else None
        self.sinks: list[Sink] = [TensorBoardSink(run_dir / "tensorboard", purge_step=purge_step)]
        if wandb:
            config = json.loads((run_dir / "config.json").read_text())
            suffix = try_suffix(try_index)
            run_id = wandb_run_id(run_dir.name, provenance.first_provenance(run_dir)) + suffix
            self.sinks.append(WandbSink(wandb, run_dir, config, run_id, run_dir.name + suffix))
        stack.enter_context(closing(self.sinks))
        self.bar = stack.enter_context(progress.Progress(trainer.num_updates * trainer.env_steps_per_update))
        self.file = stack.enter_context((run_dir / "metrics.jsonl").open("a"))
        self.bar.advance_to(resumed_at)

    def write(self, rows: list[dict], env_steps: int, flat: dict[str, np.ndarray]) -> None:
        for row in rows:
            self.file.write(json.dumps(row) + "\n")
            for sink in self.sinks:
                sink.write(row)
        self.file.flush()
        self.bar.update(env_steps, rows[-1]["steps_per_second"], flat)


@contextlib.contextmanager
def closing(sinks: Sequence[Sink]) -> Iterator[None]:
    """Closes `sinks` after the `with` block. While an error propagates, a sink that fails to close (its last
    events cannot be written on a full disk) is reported in one line, so that it does not hide that error."""
    try:
        yield
    except BaseException:
        for sink in sinks:
            try:
                sink.close()
            except Exception as error:
                print(f"also: {type(sink).__name__} could not be closed ({error})", file=sys.stderr)
        raise
    for sink in sinks:
        sink.close()
