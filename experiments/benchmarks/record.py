"""A suite's figures as JSON beside the markdown it prints, so that BENCHMARKS.md's figures are pasted, not retyped.

Every suite takes `--out DIR` (`add_out_argument`) and ends by calling `write_record`, which writes
`DIR/<suite>.json`: the device, the date, the command line that reproduces the run and the suite's rows (one
object per printed table row, numbers unrounded), plus whatever the suite measured outside its table.
"""

import argparse
import datetime
import json
import math
import pathlib
import shlex
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np

DEFAULT_OUT = "runs/bench"


def add_out_argument(parser: argparse.ArgumentParser) -> None:
    """Adds `--out DIR`, where `write_record` puts `<suite>.json`."""
    parser.add_argument("--out", default=DEFAULT_OUT, help=f"folder for <suite>.json (default {DEFAULT_OUT})")


def command_line(suite: str, argv: Sequence[str]) -> str:
    """The shell command that runs `suite` with `argv`."""
    return shlex.join(["python", "-m", "experiments.bench", suite, *argv])


def plain(value: Any) -> Any:
    """`value` with numpy scalars as Python numbers and non-finite floats as None (strict JSON has no NaN)."""
    if isinstance(value, dict):
        return {key: plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [plain(item) for item in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_record(
    out_dir: str | pathlib.Path, suite: str, argv: Sequence[str], rows: Sequence[dict[str, Any]], **extra: Any
) -> pathlib.Path:
    """Writes `out_dir/<suite>.json` and returns its path.

    Args:
      out_dir: folder, created if missing.
      suite: the suite's name, as `python -m experiments.bench` takes it.
      argv: the suite's own arguments (after the suite's name), for the command line.
      rows: one dict per table row, keys as the table's columns.
      extra: further named figures (scalars, dicts or lists), stored beside the rows. NaNs (a figure not
        measured) are written as null.
    """
    record = {
        "suite": suite,
        "device": jax.devices()[0].device_kind,
        "device_count": jax.device_count(),
        "jax": jax.__version__,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "command": command_line(suite, argv),
        **extra,
        "rows": list(rows),
    }
    path = pathlib.Path(out_dir) / f"{suite}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(plain(record), indent=1, allow_nan=False) + "\n")
    print(f"figures: {path}", flush=True)
    return path
