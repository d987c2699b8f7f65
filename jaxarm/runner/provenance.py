"""Where a run came from: the code's git commit, package versions, devices, command line, host and time.

`record(event)` builds one record of this process; `append_provenance` adds it to a directory's provenance.json
(`rundir.PROVENANCE_FILE`): training when a run starts and at each resume that trains, a sweep when it starts. A
record changes nothing that is computed; it lets a result be traced to the code and the software that produced it.
"""

import datetime
import importlib.metadata
import json
import pathlib
import platform
import socket
import subprocess
import sys

import jax

from jaxarm.runner.rundir import PROVENANCE_FILE, damaged, write_json

PACKAGES = ("jax", "jaxlib", "mujoco", "mujoco-mjx", "brax", "flax", "optax", "orbax-checkpoint", "numpy", "warp-lang")
"""Distributions whose versions a record holds (None for one not installed, as warp-lang often is)."""
CHECKOUT = pathlib.Path(__file__).resolve().parents[2]
"""The directory above the jaxarm package: a git checkout when jaxarm runs from one (an editable install)."""


def package_versions(names=PACKAGES) -> dict[str, str | None]:
    """{distribution: installed version or None}, and "python": the interpreter's version."""
    versions: dict[str, str | None] = {"python": platform.python_version()}
    for name in names:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def git_state(directory: pathlib.Path = CHECKOUT) -> dict[str, str | bool | None]:
    """{"commit": HEAD's hash, "dirty": whether tracked files differ from it} of the checkout `directory`; both
    None where it is no git checkout (an installed wheel) or git is missing."""

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(directory), *args], capture_output=True, text=True, timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout if done.returncode == 0 else None

    inside = git("rev-parse", "--show-toplevel")
    if inside is None or pathlib.Path(inside.strip()).resolve() != directory.resolve():
        return {"commit": None, "dirty": None}
    commit = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no")
    return {
        "commit": commit.strip() if commit else None,
        "dirty": None if status is None else bool(status.strip()),
    }


def record(event: str) -> dict:
    """One provenance record of this process, now; `event` says what it marks ("start", "resume", "sweep")."""
    return {
        "event": event,
        "time": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "command": [sys.executable, *sys.argv],
        "cwd": str(pathlib.Path.cwd()),
        "hostname": socket.gethostname(),
        "git": git_state(),
        "packages": package_versions(),
        "devices": [f"{device.platform}:{device.id} {device.device_kind}" for device in jax.devices()],
    }


def read_provenance(path: pathlib.Path) -> list:
    """The records of the provenance.json at `path`; RunDirError naming it where it is damaged or edited, which is
    never written over (it holds the run's history)."""
    try:
        records = json.loads(path.read_text())["records"]
        if not isinstance(records, list):
            raise TypeError("records is not a list")
    except (ValueError, KeyError, TypeError) as error:  # ValueError: JSONDecodeError, UnicodeDecodeError
        raise damaged(path, error) from None
    return records


def append_provenance(directory: pathlib.Path, event: str) -> dict:
    """Adds `record(event)` to `directory`'s provenance.json and returns it; RunDirError naming the file
    where it is damaged."""
    path = directory / PROVENANCE_FILE
    records = read_provenance(path) if path.exists() else []
    entry = record(event)
    write_json(path, {"records": [*records, entry]})
    return entry


def first_provenance(directory: pathlib.Path) -> dict:
    """The first record of `directory`'s provenance.json: where, when and how training first started there."""
    return read_provenance(directory / PROVENANCE_FILE)[0]
