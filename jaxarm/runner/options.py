"""How a run is driven, beside its config: `Options`, read by the run loop (loop.py), its chunks (chunks.py) and
the teacher stage (teacher.py). Nothing here changes what a run computes."""

import dataclasses
from collections.abc import Callable, Sequence

import jax

from jaxarm.agents.common.config import RunConfig
from jaxarm.runner.sinks import WandbOptions


@dataclasses.dataclass(frozen=True)
class Options:
    """How a run is driven, beside its config (nothing here changes what it computes).

    Attributes:
      stop_after_s: checkpoint and stop after the first chunk that ends past this many seconds (resume later).
      wandb: also log to this wandb project; None for no wandb.
      on_chunk: called with the update count after each chunk's rows are logged (e.g. to watch a run).
      devices: the devices to split the env batch over; None for every device of every process.
      presets: preset name -> its config (`experiments.configs.get`): how a teacher named by preset
        (`teacher=preset:NAME`) is found, before it has been trained; the library holds no presets.
    """

    stop_after_s: float | None = None
    wandb: WandbOptions | None = None
    on_chunk: Callable[[int], None] | None = None
    devices: Sequence[jax.Device] | None = None
    presets: Callable[[str], RunConfig] | None = None
