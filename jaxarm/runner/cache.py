"""JAX's persistent compilation cache, on by default for the runner's commands (run, eval, sweep, bench).

A second command that compiles the same program (same config, jax version and device) reads it from disk
instead of compiling again: MJX programs compile for about a minute each. The cache lives in
`~/.cache/jaxarm/jax` (or `$XDG_CACHE_HOME/jaxarm/jax`); `JAXARM_COMPILATION_CACHE=DIR` moves it and
`JAXARM_COMPILATION_CACHE=off` turns it off. A cache set through JAX's own `JAX_COMPILATION_CACHE_DIR` is left
as it is. Programs that compile in under half a second are not worth a disk write and are left out (JAX's
`JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS` changes that).
"""

import os
import pathlib

ENV_VAR = "JAXARM_COMPILATION_CACHE"
OFF = ("", "0", "off", "false", "no")
MIN_COMPILE_SECONDS = 0.5


def cache_dir(environ=os.environ) -> pathlib.Path | None:
    """The directory the cache should use under `environ`, or None where it is off or JAX's own is set."""
    if environ.get("JAX_COMPILATION_CACHE_DIR"):
        return None
    chosen = environ.get(ENV_VAR)
    if chosen is not None:
        return None if chosen.strip().lower() in OFF else pathlib.Path(chosen).expanduser()
    base = pathlib.Path(environ.get("XDG_CACHE_HOME") or pathlib.Path(environ.get("HOME", "~")).expanduser() / ".cache")
    return base / "jaxarm" / "jax"


def enable_compilation_cache() -> pathlib.Path | None:
    """Points JAX's persistent cache at `cache_dir()` (before the first compile); returns it, or None."""
    import jax

    directory = cache_dir()
    if directory is None:
        return None
    directory.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(directory))
    if "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS" not in os.environ:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    return directory
