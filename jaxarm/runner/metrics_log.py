"""A run's metrics log, metrics.jsonl (one JSON row per update, in the run directory of rundir.py): reading it,
cutting it back to a resumed checkpoint, naming the rows it lacks, and a learner's metrics flattened into a row's
columns. The rows are appended between chunks by runlog.py.
"""

import dataclasses
import json
import pathlib

import numpy as np

from jaxarm.runner.rundir import RunDirError

ROW_NUMBERS: dict[str, type | tuple[type, ...]] = {"updates": int, "env_steps": int, "wall_time": (int, float)}
"""The columns every row holds (runlog.py), with their types: a resume reads them (an edited row's "updates"
of "x" or a row without it ended the resume in a traceback)."""


def read_metrics(run_dir: pathlib.Path, drop_partial_last: bool = False) -> list[dict]:
    """The rows of `run_dir/metrics.jsonl` ([] if there is none). RunDirError naming the file and line for a row
    that is not JSON, or lacks a number of `ROW_NUMBERS`; with `drop_partial_last`, a last line without its
    newline (a process killed while writing it) is left out instead."""
    path = run_dir / "metrics.jsonl"
    if not path.exists():
        return []
    text = path.read_bytes()  # bytes: a line that is not UTF-8 is named like any other damaged line
    lines = text.split(b"\n")
    if drop_partial_last and lines and not text.endswith(b"\n"):
        lines = lines[:-1]
    rows = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
            if not isinstance(row, dict):
                raise TypeError(f"a JSON {type(row).__name__}, not an object")
            wrong = [name for name, kind in ROW_NUMBERS.items() if not isinstance(row.get(name), kind)]
            if wrong:
                raise TypeError(f"no {' or '.join(wrong)} of the right type")
        except (ValueError, TypeError) as error:  # ValueError: JSONDecodeError, UnicodeDecodeError
            raise RunDirError(f"{path} line {number} is not a JSON row ({error}); delete that line and retry") from None
        rows.append(row)
    return rows


def truncate_metrics(run_dir: pathlib.Path, max_update: int) -> list[dict]:
    """Drops metric rows after `max_update` (rows a killed run logged past its last checkpoint, or half wrote);
    returns the rows kept."""
    rows = [row for row in read_metrics(run_dir, drop_partial_last=True) if row["updates"] <= max_update]
    (run_dir / "metrics.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    return rows


def missing_metrics(run_dir: pathlib.Path, rows: list[dict], done_updates: int) -> str | None:
    """None where `rows` (metrics.jsonl's) hold one row for each of the `done_updates` a resumed checkpoint has
    done; else, in one line, which are missing (metrics.jsonl cut short, deleted or edited) and that the run goes
    on: the checkpoint holds all that training needs, and refusing would not bring the rows back."""
    logged = {row.get("updates") for row in rows}
    missing = [update for update in range(1, done_updates + 1) if update not in logged]
    if not missing:
        return None
    spans: list[list[int]] = []
    for update in missing:
        if spans and spans[-1][1] == update - 1:
            spans[-1][1] = update
        else:
            spans.append([update, update])
    shown = ", ".join(str(low) if low == high else f"{low}-{high}" for low, high in spans[:3])
    return (
        f"{run_dir / 'metrics.jsonl'} lacks the rows of updates {shown}{', ...' if len(spans) > 3 else ''} "
        f"({len(missing):,} of the {done_updates:,} the checkpoint has done: cut short, deleted or edited); resuming "
        "from the checkpoint, which holds all training needs; the curve will have that gap"
    )


def flatten_metrics(metrics, prefix: str = "") -> dict[str, np.ndarray]:
    """A (nested) flax struct of arrays [K] -> {"episodes/return_mean": array [K], ...}."""
    if not dataclasses.is_dataclass(metrics):
        return {prefix.rstrip("/"): np.asarray(metrics)}
    flat = {}
    for field in dataclasses.fields(metrics):
        flat.update(flatten_metrics(getattr(metrics, field.name), f"{prefix}{field.name}/"))
    return flat
