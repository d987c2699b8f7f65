"""How a run is driven, beside its config: `Options`, read by the run loop (loop.py), its chunks (chunks.py) and
the teacher stage (teacher.py). Nothing here changes what a run computes."""

import dataclasses
import time
from collections.abc import Callable, Sequence

import jax

from jaxarm.agents.common.config import RunConfig
from jaxarm.runner.sinks import WandbOptions


@dataclasses.dataclass(frozen=True)
class Options:
    """How a run is driven, beside its config (nothing here changes what it computes).

    Attributes:
      stop_after_s: checkpoint and stop after the first chunk that ends past this many seconds from `clock_start`
        (resume later): everything the run does counts, its stages, compilations and evaluations included.
      clock_start: when that time limit's clock started (`time.perf_counter()`); None until `train` or `resume`
        starts it, which a stage's run, trained inside its run, finds started.
      wandb: also log to this wandb project; None for no wandb.
      on_chunk: called with the update count after each chunk's rows are logged (e.g. to watch a run).
      devices: the devices to split the env batch over; None for every device of every process.
      presets: preset name -> its config (`experiments.configs.get`): how a teacher named by preset
        (`teacher=preset:NAME`) is found, before it has been trained; the library holds no presets.
    """

    stop_after_s: float | None = None
    clock_start: float | None = None
    wandb: WandbOptions | None = None
    on_chunk: Callable[[int], None] | None = None
    devices: Sequence[jax.Device] | None = None
    presets: Callable[[str], RunConfig] | None = None

    def clock_started(self) -> "Options":
        """These options with the time limit's clock started now, unless it has started already."""
        return self if self.clock_start is not None else dataclasses.replace(self, clock_start=time.perf_counter())

    def out_of_time(self) -> bool:
        """Whether the time limit has passed since its clock started (`clock_started`); False without a limit."""
        if self.stop_after_s is None:
            return False
        if self.clock_start is None:
            raise ValueError("the time limit's clock has not started: call clock_started() first")
        return time.perf_counter() - self.clock_start > self.stop_after_s
