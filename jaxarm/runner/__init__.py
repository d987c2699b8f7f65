"""The runner as a library: train into a run directory with checkpoints, metrics, progress, NaN stop and
evaluation (`train`, `resume`), and read runs back (`load_run`, `read_metrics`).

`python -m experiments.run` (the CLI), `experiments.eval` and `experiments.sweep` are thin layers over this.
"""

from jaxarm.runner.loop import Options, TrainingDiverged, TrainingInterrupted, load_run, resume, train
from jaxarm.runner.metrics_log import read_metrics
from jaxarm.runner.rundir import RunDirError, read_config
from jaxarm.runner.sinks import WandbOptions

__all__ = [
    "Options",
    "RunDirError",
    "TrainingDiverged",
    "TrainingInterrupted",
    "WandbOptions",
    "load_run",
    "read_config",
    "read_metrics",
    "resume",
    "train",
]
