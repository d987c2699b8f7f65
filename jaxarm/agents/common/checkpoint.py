"""Whole-learner-state checkpoints with orbax, and clear errors for missing, corrupt or mismatched ones.

Saves are synchronous so that a checkpoint on disk is complete (orbax writes to a temporary folder,
`<step>.orbax-checkpoint-tmp-<time>`, and renames it), and a process killed at any moment, or a disk that fills
up, leaves the last finished checkpoint intact; the next save clears such temporary folders. Restoring never
writes.
"""

import contextlib
import errno
import logging
import os
import pathlib
import warnings
from collections.abc import Callable
from typing import Any

import jax
import orbax.checkpoint as ocp

from jaxarm.unraisable import drop_unraisable


class CheckpointError(RuntimeError):
    """A checkpoint is missing, unreadable, or does not match the learner it is restored into."""


@contextlib.contextmanager
def _quiet_orbax():
    """Silences orbax's absl ERROR lines while checkpoints are read or written: a damaged checkpoint logs one per
    file per look, a full disk a 40-line traceback from orbax's writing thread, and the CheckpointError raised
    here already says which checkpoint is at fault and why."""
    logger = logging.getLogger("absl")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


TEMPORARY_SUFFIX = ".orbax-checkpoint-tmp"
"""Marks the folder of a checkpoint still being written (or left half-written by a kill or a full disk)."""


def _manager(directory: pathlib.Path, create: bool = False) -> ocp.CheckpointManager:
    # Reading managers are made with create=False (orbax's read_only mode only logs warnings here); writing ones
    # clear the temporary folders of saves that never finished.
    options = ocp.CheckpointManagerOptions(
        max_to_keep=2, enable_async_checkpointing=False, create=create, cleanup_tmp_directories=create
    )
    return ocp.CheckpointManager(directory.absolute(), options=options)


STATE_ITEM = "default"
"""The folder in a checkpoint's step folder that holds the learner state (orbax's name for a manager's one item)."""


def half_written(directory: pathlib.Path) -> list[str]:
    """Names of the unfinished checkpoints (temporary folders) in `directory`, sorted."""
    if not directory.is_dir():
        return []
    return sorted(path.name for path in directory.iterdir() if TEMPORARY_SUFFIX in path.name)


def save(directory: pathlib.Path, step: int, state) -> None:
    """Saves the learner state pytree as checkpoint `step` (the update count) under `directory`.

    Raises CheckpointError, in one line that names the cause (a full disk, no permission), when it cannot be
    written; the checkpoints saved before are intact.
    """
    try:
        with _abandoned_writes_quiet(), _quiet_orbax(), _manager(directory, create=True) as manager:
            manager.save(step, args=ocp.args.StandardSave(state), force=True)
    except Exception as error:  # orbax and tensorstore wrap OS errors in many types
        raise CheckpointError(
            f"cannot write checkpoint {step} in {directory}: {_cause(error)} (checkpoints saved before are intact)"
        ) from error


@contextlib.contextmanager
def _abandoned_writes_quiet():
    """Keeps off stderr what the writes of a save that fails inside the block print: orbax closes its event loop at
    the first failed write, and each write still in flight reports "Event loop is closed" as an unraisable error (a
    traceback each: up to 190 on a full disk, in 7 of 12 tries on a 300 KB tmpfs), then a warning of a coroutine
    never awaited; a write that fails only after the save has raised logs its own absl ERROR traceback from orbax's
    thread (38 lines, 2 of 40 sweeps on a file-size limit), past `_quiet_orbax`. Where the save fails this stays so
    for the rest of the process (the writes end after it); the CheckpointError raised says what failed."""
    put_back = drop_unraisable(lambda error: isinstance(error, RuntimeError) and str(error) == "Event loop is closed")
    try:
        yield
    except BaseException:
        warnings.filterwarnings("ignore", message="coroutine .* was never awaited", category=RuntimeWarning)
        logging.getLogger("absl").addFilter(_not_from_orbax)
        raise
    put_back()


def _not_from_orbax(record: logging.LogRecord) -> bool:
    """Whether a log record comes from outside orbax's own code (a logging filter)."""
    return "orbax" not in pathlib.Path(record.pathname).parts


def _cause(error: BaseException) -> str:
    """The OS error behind `error` in words (e.g. "No space left on device"), else its first line."""
    seen: BaseException | None = error
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno is not None:
            return os.strerror(seen.errno)
        for code in (errno.ENOSPC, errno.EACCES, errno.EROFS, errno.EDQUOT, errno.EFBIG):
            if os.strerror(code) in str(seen):
                return os.strerror(code)
        seen = seen.__cause__ or seen.__context__
    return f"{type(error).__name__}: {str(error).splitlines()[0][:200] if str(error) else ''}"


_LISTING_ATTEMPTS = 3
"""Looks at a checkpoint folder before a vanishing step is reported as an error (see `latest_step`)."""


def latest_step(directory: pathlib.Path) -> int | None:
    """The newest complete checkpoint's step, or None if there is none."""
    if not directory.exists():
        return None
    for _ in range(_LISTING_ATTEMPTS - 1):
        try:
            return _listed_latest_step(directory)
        except (FileNotFoundError, NotADirectoryError):
            # A live run prunes old steps (max_to_keep) while another process lists them (a test or a viewer
            # watching it): orbax then stats a step folder that has just gone, or finds it there and then not a
            # folder (its `exists()` then `is_dir()`: NotADirectoryError, seen once in CI). Looking again sees the
            # new list.
            pass
    return _listed_latest_step(directory)


def _listed_latest_step(directory: pathlib.Path) -> int | None:
    with _quiet_orbax(), _manager(directory) as manager:
        return manager.latest_step()


def restore(
    directory: pathlib.Path,
    like,
    step: int | None = None,
    shardings=None,
    fresh: Callable[[], Any] | None = None,
    partial: bool = False,
):
    """Restores the checkpoint `step` (default: latest) into the structure, shapes and dtypes of `like`, placed
    with `shardings` (a pytree of shardings like `like`; None: every leaf on this process's first device).

    With `partial`, a part of the checkpoint that `like` leaves None is not read (a learner state for acting,
    whose envs' state is None: a sorter's 8,192 envs are most of its checkpoint).

    A checkpoint saved before the learner gained leaves (an env param added since, in the envs' state) restores
    with those leaves taken from `fresh()` (a state like `like`, placed the same), with a warning naming them; no
    other difference is forgiven. Raises CheckpointError when there is no checkpoint, or when it cannot be read
    into `like`.
    """
    step = latest_step(directory) if step is None else step
    if step is None:
        raise CheckpointError(f"no checkpoint found in {directory}")
    _check_holds_a_state(directory, step)
    # Every leaf is placed as asked: left to itself, orbax places a leaf as it was saved, and refuses a checkpoint
    # written on other devices (a GPU run evaluated on a laptop, 4 processes' run resumed by 1).
    if shardings is None:
        here = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
        shardings = jax.tree.map(lambda _: here, like)
    abstract = jax.tree.map(
        lambda leaf, sharding: jax.ShapeDtypeStruct(leaf.shape, leaf.dtype, sharding=sharding), like, shardings
    )
    wanted = {_leaf_name(path): leaf for path, leaf in jax.tree_util.tree_flatten_with_path(abstract)[0]}
    saved = _saved_metadata(directory, step)
    added: list[str] = []
    if saved is not None:  # else orbax's reading fails below, and says why
        saved_shapes = {leaf.name: (tuple(leaf.shape), leaf.dtype) for leaf in jax.tree.leaves(saved)}
        added = sorted(set(wanted) - set(saved_shapes)) if fresh is not None else []
        left_out = tuple(_left_out(abstract)) if partial else ()
        mismatch = _mismatch(saved_shapes, wanted, left_out, added)
        if mismatch:
            raise CheckpointError(
                f"checkpoint {step} in {directory} cannot be restored into this learner (saved by a different "
                f"config): {mismatch}"
            )
    args = (
        ocp.args.PyTreeRestore(abstract, ocp.checkpoint_utils.construct_restore_args(abstract), partial_restore=True)
        if partial
        else ocp.args.StandardRestore(abstract)
    )
    try:
        if added and fresh is not None:
            restored = _restore_with_additions(directory, step, saved, wanted, added, fresh)
        else:
            with _quiet_orbax(), _manager(directory) as manager:
                restored = manager.restore(step, args=args)
    except Exception as error:  # orbax raises many types for corrupt trees
        raise CheckpointError(
            f"checkpoint {step} in {directory} cannot be restored into this learner (corrupt): {_cause(error)}"
        ) from None
    _check_matches(restored, like, directory, step)
    return restored


def _saved_metadata(directory: pathlib.Path, step: int):
    """The tree of checkpoint `step`'s leaves as saved (orbax's metadata: each leaf's name, shape and dtype); None
    where it cannot be read (a corrupt checkpoint)."""
    try:
        with _quiet_orbax():
            return ocp.StandardCheckpointer().metadata(directory.absolute() / str(step) / STATE_ITEM).item_metadata
    except Exception:  # orbax and tensorstore raise many types
        return None


def _mismatch(saved: dict[str, tuple], wanted: dict[str, Any], left_out: tuple[str, ...], added: list[str]) -> str:
    """How a checkpoint's leaves (`saved`: name -> shape and dtype) differ from those a learner restores (`wanted`:
    name -> ShapeDtypeStruct), up to three differences in words; "" where they fit. Leaves under `left_out` are not
    read, and those in `added` (new since the checkpoint) come from a fresh state."""
    read = {name: shape for name, shape in saved.items() if not name.startswith(left_out)}
    differences = [
        f"{name} is {_shape(*read[name])} there, {_shape(wanted[name].shape, wanted[name].dtype)} here"
        for name in sorted(read.keys() & wanted.keys())
        if read[name] != _as_saved(wanted[name])
    ]
    differences += [f"it lacks {name}" for name in sorted(wanted.keys() - saved.keys() - set(added))]
    differences += [f"it holds {name}, which this learner lacks" for name in sorted(read.keys() - wanted.keys())]
    return "; ".join(differences[:3]) + ("; ..." if len(differences) > 3 else "")


def _as_saved(leaf: jax.ShapeDtypeStruct) -> tuple:
    """`leaf`'s shape and dtype as a checkpoint holds it: a typed PRNG key (`key<fry>` [N]) as its key data
    (uint32 [N, 2])."""
    if jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key):
        leaf = jax.eval_shape(jax.random.key_data, leaf)
    return tuple(leaf.shape), leaf.dtype


def _shape(shape: tuple, dtype) -> str:
    return f"{tuple(shape)} {dtype}"


def _check_holds_a_state(directory: pathlib.Path, step: int) -> None:
    """CheckpointError naming the folder of checkpoint `step` where it holds no learner state (an empty folder, made
    by hand or by a copy cut short), and the checkpoint before it that does: orbax lists any folder named by a
    number as a checkpoint, and said of an empty one only "Must provide `args` of type `Composite` ..."."""
    folder = directory / str(step)
    if (folder / STATE_ITEM).is_dir():
        return
    what = "is an empty folder" if folder.is_dir() and not any(folder.iterdir()) else f"holds no {STATE_ITEM}/"
    earlier = [
        int(path.name)
        for path in directory.iterdir()
        if path.name.isdigit() and int(path.name) < step and (path / STATE_ITEM).is_dir()
    ]
    before = f" to go on from checkpoint {max(earlier)}" if earlier else ""
    raise CheckpointError(f"{folder} {what}: not a checkpoint; move it out of {directory}{before}")


def _leaf_name(path) -> str:
    """A leaf's path as orbax names it in a checkpoint (`env_state.sim.params.mass_scale`)."""
    return jax.tree_util.keystr(path, simple=True, separator=".")


def _restore_with_additions(
    directory: pathlib.Path, step: int, saved, wanted: dict[str, Any], added: list[str], fresh: Callable[[], Any]
):
    """The tree of a learner state from checkpoint `step` (its leaves as `saved`, orbax's metadata), where the
    learner has gained the leaves `added` since (`wanted`: name -> ShapeDtypeStruct of the learner's leaves): the
    saved leaves restored, the others from `fresh()`, with a warning naming them."""
    # Any part a partial restore leaves out is read too (as saved, onto the first device): old checkpoints only.
    here = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
    target = jax.tree.map(
        lambda leaf: wanted.get(leaf.name, jax.ShapeDtypeStruct(leaf.shape, leaf.dtype, sharding=here)), saved
    )
    with _quiet_orbax(), _manager(directory) as manager:
        restored = manager.restore(step, args=ocp.args.StandardRestore(target))
    by_name = {_leaf_name(path): leaf for path, leaf in jax.tree_util.tree_flatten_with_path(restored)[0]}
    warnings.warn(
        f"checkpoint {step} in {directory} predates {len(added)} leaves of this learner ({', '.join(added[:4])}"
        f"{', ...' if len(added) > 4 else ''}): they take a fresh state's values",
        stacklevel=3,
    )
    return jax.tree_util.tree_map_with_path(lambda path, leaf: by_name.get(_leaf_name(path), leaf), fresh())


def _left_out(abstract) -> list[str]:
    """The name prefixes (`env_state.`) of the parts that `abstract` leaves None."""
    parts = jax.tree_util.tree_flatten_with_path(abstract, is_leaf=lambda node: node is None)[0]
    return [_leaf_name(path) + "." for path, node in parts if node is None]


def _check_matches(restored, like, directory, step) -> None:
    restored_leaves, like_leaves = jax.tree.leaves(restored), jax.tree.leaves(like)
    for got, want in zip(restored_leaves, like_leaves, strict=True):
        if got.shape != want.shape or got.dtype != want.dtype:
            raise CheckpointError(
                f"checkpoint {step} in {directory} does not match this learner: a leaf has shape "
                f"{got.shape} {got.dtype}, expected {want.shape} {want.dtype}"
            )
