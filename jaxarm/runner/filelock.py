"""The non-blocking exclusive file lock a run directory (`rundir.locked`) and a GPU a seeds study runs on
(`experiments.seeds.GpuPool`) are held by: flock, which the OS drops with the process that held it."""

import errno
import fcntl
from typing import IO


def try_lock(handle: IO) -> bool:
    """Takes an exclusive lock (flock) on the open file `handle` for as long as it stays open; False, taking
    nothing, where another open file holds it."""
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as error:
        if error.errno not in (errno.EAGAIN, errno.EACCES):
            raise
        return False
    return True
