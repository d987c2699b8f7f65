"""Training progress after each chunk (env steps, steps/s, return, success, ETA): a rich progress bar on a
terminal, one plain line per chunk otherwise, so that a run under nohup, SLURM or CI logs its progress too."""

import datetime
import sys
import time

import jax
import numpy as np
from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.progress import Progress as RichProgress


def chunk_stats(steps_per_second: float, flat_metrics: dict) -> str:
    """'2,345 steps/s  return 1.23  success 45.0%' of one chunk: return weighted by the episodes each update
    finished, training success by those it judged (`jaxarm.agents.common.trainer.summarise_episodes`;
    `flat_metrics` maps names to arrays [updates])."""

    def weighted(name: str, weights: np.ndarray) -> float:
        return (flat_metrics[name] * weights).sum() / np.maximum(weights.sum(), 1.0)

    episodes = flat_metrics.get("episodes/episodes", np.zeros(1))
    mean_return = weighted("episodes/return_mean", episodes)
    success = weighted("episodes/success_rate", flat_metrics.get("episodes/judged", episodes))
    return f"{steps_per_second:,.0f} steps/s  return {mean_return:.2f}  success {success:.1%}"


def progress_line(env_steps: int, total_env_steps: int, stats: str, elapsed_s: float, steps_per_second: float) -> str:
    """One log line for a chunk's end; the ETA assumes the rest runs at the last chunk's rate."""
    remaining_s = max(total_env_steps - env_steps, 0) / max(steps_per_second, 1e-9)
    return (
        f"env steps {env_steps:,}/{total_env_steps:,} ({env_steps / max(total_env_steps, 1):.0%})  {stats}  "
        f"elapsed {_clock(elapsed_s)}  ETA {_clock(remaining_s)}"
    )


SLOW_COMPILE_NOTE = (
    "note: MJX programs compile for minutes on a CPU, and XLA logs 'Very slow compile? If you want to file a bug "
    "...' banners meanwhile: expected here, not a bug. Compiled programs are cached for the next command."
)
_slow_compiles_explained = False


def explain_slow_compiles(env) -> None:
    """Prints SLOW_COMPILE_NOTE on stderr, once per process, before a program stepping `env` compiles where the
    note applies (an env that steps MJX, on a CPU). XLA's banner has no switch of its own: hiding it would need
    every C++ error log hidden with it (TF_CPP_MIN_LOG_LEVEL=3)."""
    global _slow_compiles_explained
    if _slow_compiles_explained or not getattr(env, "unwrapped", env).uses_mjx or jax.default_backend() != "cpu":
        return
    _slow_compiles_explained = True
    print(SLOW_COMPILE_NOTE, file=sys.stderr, flush=True)


GSPMD_NOTE = (
    "note: XLA warns 'GSPMD sharding propagation is going to be deprecated' as it compiles a run over several "
    "devices: jaxarm partitions such runs with GSPMD, because Shardy crashed XLA:GPU compiling the sorter's update "
    "(jaxarm/agents/common/sharding.py); expected here, not a fault."
)
_gspmd_explained = False


def explain_gspmd(devices: int) -> None:
    """Prints GSPMD_NOTE on stderr, once per process, before a run over `devices` devices compiles, where it
    applies (more than one: `sharding.data_mesh` then chooses GSPMD). XLA's warning has no switch of its own."""
    global _gspmd_explained
    if _gspmd_explained or devices < 2:
        return
    _gspmd_explained = True
    print(GSPMD_NOTE, file=sys.stderr, flush=True)


def _clock(seconds: float) -> str:
    return str(datetime.timedelta(seconds=round(seconds)))


class Progress:
    """Context manager: `update(env_steps, steps_per_second, flat_metrics)` after each chunk.

    On a terminal (stderr a tty) a bar redrawn in place; elsewhere a line per chunk on stderr (`progress_line`).
    """

    def __init__(self, total_env_steps: int):
        self.enabled = sys.stderr.isatty()
        self.total_env_steps = total_env_steps
        self.started = time.perf_counter()
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
        stats = chunk_stats(steps_per_second, flat_metrics)
        if self.enabled:
            self.bar.update(self.task, completed=env_steps, stats=stats)
            return
        elapsed = time.perf_counter() - self.started
        print(progress_line(env_steps, self.total_env_steps, stats, elapsed, steps_per_second), file=sys.stderr)
        sys.stderr.flush()
