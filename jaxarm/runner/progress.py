"""A rich progress bar over env steps (steps/s, return, success, ETA); silent when stderr is not a tty."""

import sys

import numpy as np
from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.progress import Progress as RichProgress


class Progress:
    """Context manager: `update(env_steps, steps_per_second, flat_metrics)` after each chunk."""

    def __init__(self, total_env_steps: int):
        self.enabled = sys.stderr.isatty()
        self.bar = RichProgress(
            TextColumn("[bold]env steps"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[stats]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            disable=not self.enabled,
        )
        self.task = self.bar.add_task("train", total=total_env_steps, stats="")

    def __enter__(self):
        self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        self.bar.__exit__(*exc)

    def advance_to(self, env_steps: int) -> None:
        self.bar.update(self.task, completed=env_steps)

    def update(self, env_steps: int, steps_per_second: float, flat_metrics: dict) -> None:
        episodes = flat_metrics.get("episodes/episodes", np.zeros(1))
        weight = np.maximum(episodes.sum(), 1.0)
        mean_return = (flat_metrics["episodes/return_mean"] * episodes).sum() / weight
        success = (flat_metrics["episodes/success_rate"] * episodes).sum() / weight
        stats = f"{steps_per_second:,.0f} steps/s  return {mean_return:.2f}  success {success:.1%}"
        self.bar.update(self.task, completed=env_steps, stats=stats)
