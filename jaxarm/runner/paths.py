"""Paths a command is given: whether one can be (or is) an output directory, and an OS error met at a path in one
line naming it and what to do. Nothing here writes."""

import argparse
import errno
import os
import pathlib

from jaxarm.runner.rundir import RunDirError

FILE_SUFFIXES = (".txt", ".json", ".jsonl", ".csv", ".md", ".png", ".pdf", ".svg", ".gif", ".mp4", ".npz", ".onnx")
"""Name endings of files: a directory to be made with one of these names is more likely a mistake."""


def given(text: str) -> str:
    """`--out`'s argparse type: `text`, unless empty, where `--out "$DIR"` of an unset DIR was taken for no --out
    and the files went to the default place without a word."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a path, got an empty one (leave --out out for the default)")
    return text


def check_output_dir(path: pathlib.Path, label: str = "directory") -> None:
    """RunDirError, naming `path` as `label` (a CLI passes its flag), unless it can be (or is) a directory: named
    in UTF-8, not a file, under no file, and, when it does not exist yet, with no file's name ending (`.txt`, ...).
    Missing parent folders are made later."""
    try:
        str(path).encode()
    except UnicodeEncodeError:  # orbax's checkpointer failed at the first save, after training, on such a path
        shown = os.fsencode(path).decode(errors="backslashreplace")  # printable on any console, as x\xff
        raise RunDirError(f"{label} {shown} is not a UTF-8 name; give a directory named in UTF-8") from None
    if path.exists() and not path.is_dir():
        raise RunDirError(f"{label} {path} is a file; give a directory")
    check_not_under_a_file(path, label)
    if not path.exists() and path.suffix.lower() in FILE_SUFFIXES:
        raise RunDirError(f"{label} {path} is the name of a {path.suffix} file; give a directory")


def check_not_under_a_file(path: pathlib.Path, label: str = "directory") -> None:
    """RunDirError, naming `path` as `label`, when a file stands where one of its parent folders should be."""
    for parent in path.parents:
        if parent.exists() and not parent.is_dir():
            raise RunDirError(f"{label} {path} lies under {parent}, which is a file; give a directory")


def os_error_message(error: OSError, directory: str | pathlib.Path | None = None) -> str:
    """An OS error (permission, read-only, full disk, a file in a directory's place) in one line, naming its path
    (or, for an error on an open file, which names none, the `directory` written to) and what to do."""
    advice = {
        errno.ENOSPC: "the disk is full; free space and retry (a resumed run goes on)",
        errno.EDQUOT: "the disk quota is used up; free space and retry (a resumed run goes on)",
        errno.EACCES: "not writable here; choose another place or fix its permissions",
        errno.EPERM: "not writable here; choose another place or fix its permissions",
        errno.EROFS: "choose a writable place (copy a run there to go on with it)",
        errno.ENOTDIR: "a file stands where a directory is needed; choose another path",
        errno.EEXIST: "a file of that name is in the way; choose another path",
        errno.EISDIR: "a directory stands where a file is needed; choose another path",
        errno.EPIPE: "the output's reader went away (as `| head` does); what was written before is kept",
    }.get(error.errno or 0, "")
    where = f"{error.filename}: " if error.filename else f"writing into {directory}: " if directory else ""
    return f"{where}{error.strerror or error}" + (f"; {advice}" if advice else "")
