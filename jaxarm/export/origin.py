"""export.json: which checkpoint of its run an exported policy came from (its update count, or "best"), written
beside policy.npz by `python -m experiments.export`; what runs the policy names its results by it, so that the
results of another checkpoint's policy never replace them. Imports json alone."""

import json
import pathlib

from jaxarm.export.numpy_policy import EXPORT_AGAIN, PolicyFileError

FILE = "export.json"


def record(checkpoint_name: str) -> dict:
    """export.json's content for a policy from the checkpoint `checkpoint_name` (an update count, or "best")."""
    return {"checkpoint": checkpoint_name}


def read(directory: str | pathlib.Path) -> str:
    """The checkpoint the policy in `directory` came from, as `record` wrote it; PolicyFileError naming export.json
    where it is missing (an export of an earlier version, or one cut short), damaged or edited. OSError where it
    cannot be read."""
    path = pathlib.Path(directory) / FILE
    if not path.exists():
        raise PolicyFileError(f"no {path} (which checkpoint the policy came from); {EXPORT_AGAIN}")
    try:
        name = json.loads(path.read_text())["checkpoint"]
        if not (isinstance(name, str) and (name == "best" or (name.isascii() and name.isdigit()))):
            raise ValueError(f"checkpoint {name!r} is neither an update count nor 'best'")
    except (ValueError, KeyError, TypeError) as error:  # ValueError: JSONDecodeError and UnicodeDecodeError too
        raise PolicyFileError(
            f"{path} is damaged or edited ({type(error).__name__}: {error}); {EXPORT_AGAIN}"
        ) from None
    return name
