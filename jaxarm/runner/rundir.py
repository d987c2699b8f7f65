"""A run directory, shared by training, eval and sweep: its layout, the checks and the lock that keep it whole,
its config.json, its final evaluation and the names of the files eval, export and transfer write into it.
Beside this module: metrics.jsonl is read by metrics_log.py, provenance.json written by provenance.py, what a
resume may change checked by resumes.py, a run's teacher found by teacher.py, and the paths a command is given
(an output directory, an OS error met there) checked by paths.py.

Layout of `runs/<config>-<timestamp>/`:
  config.json      the resolved config (with "preset", and "agent": the learner's name in jaxarm.agents.registry)
  provenance.json  {"records": [...]}: git commit and dirty flag, package versions, devices, command line, host
                   and time of the start and of each resume that trained (jaxarm/runner/provenance.py)
  resumes.jsonl    one JSON row per resume that changed settings: the overrides and the update it resumed at
  metrics.jsonl    one JSON row per update (evaluation during training adds "eval/..." to its update's row)
  tensorboard/     TensorBoard event files, against env steps
  checkpoints/     orbax checkpoints of the whole learner state, named by update count, and config.json: the
                   config of the latest one (an edited config.json is checked against it on resume)
  best/            the checkpoint that scored best in evaluation during training; best.json says which
  curve.png        learning curve
  eval.json        deterministic evaluation at the end of training
  eval-<episodes>-<seed>-<update|best>.json, video.gif, video.mp4   written by `experiments.eval`
  robustness-<episodes>-<seed>-<update|best>-<digest>.json, .md, .png   written by `experiments.eval --perturb`
  `transfer-<model>-<episodes>-<seed>-<update|best>[-noclip][-bias<X>_<Y>_<Z>mm].json`, .gif, .mp4   written by
    `experiments.transfer`
  rehearse-<episodes>-<seed>-<update>-<budget>ms[-<fault>-tick<K>].json   written by `experiments.rehearse`
  export/          the policy exported by `experiments.export`, and export.json: the checkpoint it came from
  teacher/         the run of a teacher named by preset (`teacher=preset:NAME`), trained first; kept when the
                   student starts afresh
  warm_start/      the run it warm-starts from, named by preset (`init_from=preset:NAME`), trained first; kept
                   likewise
  tries/K/         the metrics, TensorBoard events, checkpoints and best state of try K, set aside when it failed
                   a gate of the config (`retry_below`, `retry_train_below`), with its warm_start/ where each try
                   trains its own (`retry_warm_start`); the run trains its next try in the directory itself
  .lock            held (flock) by the one process writing to the directory

A directory becomes a run when its config.json is written (before its stages, where it has them); until its first
checkpoint, starting it again (or resuming it) starts it afresh, keeping the teacher/ and warm_start/ it has; after
a try set aside, until the next try's first checkpoint, it starts that try afresh, keeping the run's records.
Nothing here deletes or overwrites a file that is not one of the above.
"""

import contextlib
import dataclasses
import hashlib
import json
import os
import pathlib
import shutil
import time
import typing
from collections.abc import Callable, Iterator, Sequence
from typing import TypeVar

from jaxarm.agents import registry
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import RunConfig
from jaxarm.runner import filelock
from jaxarm.runner.tries import TRIES_DIR

PROVENANCE_FILE = "provenance.json"
RUN_FILES = (
    "config.json",
    PROVENANCE_FILE,
    "resumes.jsonl",
    "metrics.jsonl",
    "tensorboard",
    "checkpoints",
    "best",
    "best.json",
)
"""What training writes; with `OUTPUT_FILES`, what a run directory may hold."""
TEACHER_DIR = "teacher"
"""Where a run whose teacher is named by preset (`teacher=preset:NAME`) trains that teacher before itself."""
WARM_START_DIR = "warm_start"
"""Where a run that warm-starts from a preset (`init_from=preset:NAME`) trains that run before itself."""
OUTPUT_FILES = (
    "curve.png",
    "eval.json",
    "video.gif",
    "video.mp4",
    "export",
    ".lock",
    TEACHER_DIR,
    WARM_START_DIR,
    TRIES_DIR,
)
OUTPUT_PATTERNS = (
    "eval-*.json",
    "robustness-*.json",
    "robustness-*.md",
    "robustness-*.png",
    "transfer-*.json",
    "transfer-*.gif",
    "transfer-*.mp4",
    "rehearse-*.json",
    "wandb",
    ".*.tmp",
)


class RunDirError(ValueError):
    """A run directory cannot be used as asked (foreign files, in use, damaged); the message says what to do."""


def damaged(path: pathlib.Path, error: Exception) -> RunDirError:
    """The error of a run's file at `path` that reading it found damaged or edited (`error` says how), in one line."""
    return RunDirError(f"{path} is corrupt or of another version ({type(error).__name__}: {error}); fix or restore it")


ErrorT = TypeVar("ErrorT", bound=BaseException)


def resumable(error: ErrorT, run_dir: pathlib.Path) -> ErrorT:
    """`error`, marked as one that resuming the run in `run_dir` gets past (`error.resume_dir`). Messages here
    speak of the library (`resume`); a front end adds its own way to resume (the CLI its --resume command)."""
    error.resume_dir = pathlib.Path(run_dir)  # type: ignore[attr-defined]
    return error


def new_run_dir(preset: str, root: str = "runs") -> pathlib.Path:
    """Creates and returns a fresh `root/<preset>-<timestamp>`, with `-2`, `-3`, ... appended when a run started
    in the same second holds that name (the directory is made atomically, so parallel runs never share one)."""
    stem = pathlib.Path(root) / f"{preset}-{time.strftime('%Y%m%d-%H%M%S')}"
    stem.parent.mkdir(parents=True, exist_ok=True)
    for index in range(1, 10_000):
        path = stem if index == 1 else stem.with_name(f"{stem.name}-{index}")
        try:
            path.mkdir()
        except FileExistsError:
            continue
        return path
    raise RunDirError(f"10,000 runs named {stem}-* exist; give a run directory")


def foreign_files(run_dir: pathlib.Path) -> list[str]:
    """Names in `run_dir` that no jaxarm run writes (sorted)."""
    if not run_dir.is_dir():
        return []
    return sorted(
        path.name
        for path in run_dir.iterdir()
        if path.name not in RUN_FILES + OUTPUT_FILES and not any(path.match(pattern) for pattern in OUTPUT_PATTERNS)
    )


def check_holds_a_run_or_nothing(run_dir: pathlib.Path) -> None:
    """RunDirError, before anything is written, when `run_dir` holds files but no run (no config.json)."""
    if run_dir.is_dir() and not (run_dir / "config.json").exists():
        held = sorted(path.name for path in run_dir.iterdir() if path.name != ".lock")
        if held:
            raise RunDirError(
                f"{run_dir} holds files but no run ({', '.join(held[:5])}; no config.json); choose another run "
                "directory (nothing was written)"
            )


def any_checkpoint_files(run_dir: pathlib.Path) -> bool:
    """Whether `run_dir/checkpoints` holds a checkpoint folder (a step number), complete or damaged: a run with
    one is never started afresh, so nothing is lost. Half-written ones (orbax's temporary folders, left by a kill
    or a full disk during the save) do not count. RunDirError where `checkpoints` is there but no folder: a run
    that took that for no checkpoint started afresh, deleting its metrics."""
    directory = run_dir / "checkpoints"
    if directory.exists() and not directory.is_dir():
        raise RunDirError(
            f"{directory} is not a folder, so this run's checkpoints are not there: put the folder back to go on, or "
            "start the run in a new directory"
        )
    return directory.is_dir() and any(path.name.isdigit() for path in directory.iterdir())


def any_stage_checkpoint_files(run_dir: pathlib.Path) -> bool:
    """Whether the run in `run_dir` or a stage it trains first (`TEACHER_DIR`, `WARM_START_DIR`) holds a checkpoint:
    a run stopped in its first stage holds its progress there alone, and resumes from it."""
    return any(any_checkpoint_files(path) for path in (run_dir, run_dir / TEACHER_DIR, run_dir / WARM_START_DIR))


def _shown(names: list[str]) -> str:
    return ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")


def check_no_foreign_files(run_dir: pathlib.Path) -> None:
    """RunDirError when `run_dir` holds files no jaxarm run writes."""
    foreign = foreign_files(run_dir)
    if foreign:
        raise RunDirError(
            f"{run_dir} holds files that are not part of a jaxarm run ({_shown(foreign)}); move them out or use "
            "another directory (nothing was written)"
        )


def check_empty(directory: pathlib.Path) -> None:
    """RunDirError when `directory` holds anything but its lock: what writes there (a sweep) would replace it."""
    held = sorted(path.name for path in directory.iterdir() if path.name != ".lock") if directory.is_dir() else []
    if held:
        raise RunDirError(
            f"{directory} already holds {_shown(held)}; choose a new or empty directory (nothing was written)"
        )


@contextlib.contextmanager
def locked(
    run_dir: pathlib.Path, check: Callable[[pathlib.Path], None] = check_no_foreign_files
) -> Iterator[pathlib.Path]:
    """Holds `run_dir`'s lock for the `with` block (creating the directory if need be); RunDirError, with nothing
    written, when `check` refuses the directory (default: it holds foreign files) or another process holds the
    lock. A directory that was missing or empty and holds only the lock afterwards is removed again."""
    if run_dir.exists() and not run_dir.is_dir():
        raise RunDirError(f"{run_dir} is a file, not a run directory; choose another one")
    check(run_dir)
    created = not run_dir.exists() or not any(run_dir.iterdir())
    run_dir.mkdir(parents=True, exist_ok=True)
    path = run_dir / ".lock"
    try:
        handle = path.open("a+")
    except PermissionError:
        raise RunDirError(f"{run_dir} is not writable; copy the run somewhere writable and retry") from None
    try:
        if not filelock.try_lock(handle):
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            raise RunDirError(
                f"{run_dir} is in use by another process (pid {holder}, holding {path}); wait for it to finish "
                "or use another directory (nothing was written)"
            )
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        yield run_dir
    finally:
        if created and [entry.name for entry in run_dir.iterdir()] == [".lock"]:
            path.unlink()
            run_dir.rmdir()
        handle.close()


def clear_run(run_dir: pathlib.Path, names: Sequence[str] = (*RUN_FILES, "curve.png", "eval.json")) -> None:
    """Deletes what training wrote into `run_dir` (a run that died before its first checkpoint), nothing else; with
    `names`, those of it alone (a try's `TRY_FILES`)."""
    for name in names:
        path = run_dir / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()


def _as_tuples(value):
    return tuple(_as_tuples(item) for item in value) if isinstance(value, list) else value


def write_config(run_dir: pathlib.Path, config: RunConfig, preset: str) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    data = {"preset": preset, "agent": registry.name_of(config), **dataclasses.asdict(config)}
    write_json(run_dir / "config.json", data)


def read_config(
    run_dir: pathlib.Path, path: pathlib.Path | None = None, validate: bool = True
) -> tuple[RunConfig, str]:
    """The config saved in `run_dir` (or at `path`) and its preset name; ValueError if missing, unreadable or
    invalid. `validate=False` leaves out `config.validate()`, which builds the env and with it starts JAX's
    backend."""
    path = run_dir / "config.json" if path is None else path
    if not path.exists():
        raise RunDirError(f"{run_dir} is not a run directory: no config.json")
    try:
        data = json.loads(path.read_text())
        if not isinstance(data, dict):  # null gave an AttributeError traceback
            raise TypeError(f"a JSON {type(data).__name__}, not an object")
        preset, agent = data.pop("preset"), data.pop("agent")
        cls = registry.get(agent).config_class
        hints = typing.get_type_hints(cls)
        fields = {
            name: _as_tuples(value) if typing.get_origin(hints[name]) is tuple else value
            for name, value in data.items()
        }
        config = cls(**fields)
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
        raise damaged(path, error) from None
    if validate:
        try:
            config.validate()
        except ValueError as error:  # an edited env, or a kwarg or param the env does not know, named no file
            raise RunDirError(f"{path}: {error}") from None
    return config, preset


def finished_evaluation(run_dir: pathlib.Path, config: RunConfig) -> dict | None:
    """The final evaluation (eval.json) of a run that trained all of `config`'s updates and evaluated their end;
    None where there is more to train or to evaluate (no such file, an unreadable or edited one, or a stopped run's)."""
    latest = checkpoint.latest_step(run_dir / "checkpoints")
    result = read_evaluation(run_dir)
    return result if latest is not None and latest >= config.num_updates and result.get("finished") else None


def read_evaluation(run_dir: pathlib.Path) -> dict:
    """The last evaluation of the run in `run_dir` (its eval.json, "finished" where the run trained all its
    updates); {} where there is none yet, or an unreadable or edited one, which a resume writes again (`null` in it
    ended a resume, a seeds study or a comparison in a traceback)."""
    try:
        result = json.loads((run_dir / "eval.json").read_text())
    except (FileNotFoundError, ValueError):  # ValueError: JSONDecodeError, UnicodeDecodeError
        return {}
    return result if isinstance(result, dict) else {}


def write_json(path: pathlib.Path, data: dict) -> None:
    """Writes `data` to `path` as JSON, whole or not at all (`write_text`)."""
    write_text(path, json.dumps(data, indent=2))


def write_text(path: pathlib.Path, text: str) -> None:
    """Writes `text` to `path` whole or not at all (a temporary file renamed over it): a process killed while
    writing, or a full disk, leaves the previous file."""
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(text)
    temporary.replace(path)


def eval_path(run_dir: pathlib.Path, episodes: int, seed: int, checkpoint_name: str) -> pathlib.Path:
    """Where `experiments.eval` writes an evaluation of `episodes` episodes from `seed` of a checkpoint (its update
    count, or "best"), so evaluations of different checkpoints never replace each other (eval.json stays
    training's)."""
    return run_dir / f"eval-{episodes}-{seed}-{checkpoint_name}.json"


def robustness_stem(
    run_dir: pathlib.Path, episodes: int, seed: int, checkpoint_name: str, request: Sequence[str]
) -> pathlib.Path:
    """Where `experiments.eval --perturb` writes its table (stem of its .json, .md and .png): named as `eval_path`,
    and by a digest of the `request` (the perturbations asked for, in words), so that neither another checkpoint's
    table nor another request's replaces it; the same request of the same checkpoint writes the same table again."""
    digest = hashlib.sha256("\n".join(request).encode()).hexdigest()[:8]
    return run_dir / f"robustness-{episodes}-{seed}-{checkpoint_name}-{digest}"


def transfer_stem(
    run_dir: pathlib.Path, model: str, episodes: int, seed: int, checkpoint: str, clip: bool, pose_bias: Sequence[float]
) -> pathlib.Path:
    """Where `experiments.transfer` writes its results (stem of its .json and video): named by the Panda `model`,
    the episodes, the seed, the `checkpoint` the exported policy came from (as `eval_path` names it), `-noclip`
    where commands beyond Franka's limits were sent and `-bias<X>_<Y>_<Z>mm` where the position estimates were off
    by `pose_bias` (x, y, z in m; a decimal point written "p", as the name's only dot starts its suffix), so that no
    other transfer replaces it."""
    bias = "_".join(f"{component * 1e3:g}".replace(".", "p") for component in pose_bias)
    return run_dir / (
        f"transfer-{model}-{episodes}-{seed}-{checkpoint}{'' if clip else '-noclip'}"
        f"{f'-bias{bias}mm' if any(pose_bias) else ''}"
    )
