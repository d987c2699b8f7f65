"""Process-wide XLA settings that jaxarm applies before JAX starts its CPU backend.

jaxlib 0.10.x compiles MJX's CPU programs with the new fusion emitters, which made `jit(vmap(mjx.step))`
of a 7-joint arm ~45x slower on the 2-core CPU (90 vs 4,100 steps/s at 1,024 envs). jaxlib 0.11 fixed the
regression and aborts at start-up on the flag, so it is only ever added for jaxlib 0.10.x, only when the
user has not set it either way, and never when JAXARM_KEEP_XLA_FLAGS=1. It must not import jax.

The flag costs programs without MJX: with the fusion emitters off, XLA:CPU left PPO's SGD step on arm2d 1.4x
slower, and arm2d's env steps 1.6x slower. Where jaxarm set the flag, `compiler_options(env)` turns the emitters
back on for such a program alone (`jax.jit(..., compiler_options=...)`), so MJX programs and the rest each
compile the way that suits them.
"""

import importlib.metadata
import os
import sys

from jaxarm.headless import GL_HINT, GLImportError

CPU_FUSION_FLAG = "--xla_cpu_use_fusion_emitters"
CPU_FUSION_OPTION = CPU_FUSION_FLAG.removeprefix("--")

APPLIED_MARKER = "JAXARM_APPLIED_CPU_FLAG"
"""Set to "1" in the environment where jaxarm added the flag. Processes started from this one inherit XLA_FLAGS
with the flag already in it; the marker tells them it was jaxarm's, not the user's, so they compile every
program as their parent does (without it, a subprocess compiled arm2d with the emitters off while its parent
compiled them on, and their floats differed)."""

_cpu_flag_applied = False
"""Whether jaxarm turned the fusion emitters off for this process (here or in a parent process)."""


def _jaxlib_version() -> tuple[int, ...]:
    try:
        text = importlib.metadata.version("jaxlib")
    except importlib.metadata.PackageNotFoundError:
        return ()
    return tuple(int(part) for part in text.split(".")[:2] if part.isdigit())


def cpu_flag_wanted(jaxlib_version: tuple[int, ...], xla_flags: str, keep_flags: bool) -> bool:
    """Whether to append `--xla_cpu_use_fusion_emitters=false` for this jaxlib and XLA_FLAGS value."""
    return (not keep_flags) and jaxlib_version[:2] == (0, 10) and CPU_FUSION_FLAG not in xla_flags


def cpu_flag_inherited(xla_flags: str, marker: str | None, keep_flags: bool) -> bool:
    """Whether XLA_FLAGS holds the flag because a jaxarm parent process added it (`APPLIED_MARKER`)."""
    return (not keep_flags) and marker == "1" and f"{CPU_FUSION_FLAG}=false" in xla_flags


def apply_xla_settings() -> None:
    """Appends the CPU fusion flag to XLA_FLAGS where it helps (see module docstring)."""
    global _cpu_flag_applied
    flags = os.environ.get("XLA_FLAGS", "")
    keep = os.environ.get("JAXARM_KEEP_XLA_FLAGS") == "1"
    if cpu_flag_wanted(_jaxlib_version(), flags, keep):
        os.environ["XLA_FLAGS"] = f"{flags} {CPU_FUSION_FLAG}=false".strip()
        os.environ[APPLIED_MARKER] = "1"
        _cpu_flag_applied = True
    else:
        _cpu_flag_applied = cpu_flag_inherited(flags, os.environ.get(APPLIED_MARKER), keep)


def fusion_emitter_options(flag_applied: bool, uses_mjx: bool) -> dict[str, bool]:
    """XLA options of one program: the fusion emitters back on where jaxarm turned them off and the program
    steps no MJX physics; none otherwise."""
    return {CPU_FUSION_OPTION: True} if flag_applied and not uses_mjx else {}


def compiler_options(env) -> dict[str, bool]:
    """XLA options for a program that steps `env` (an env or a wrapped one), in this process: pass them to
    `jax.jit(..., compiler_options=...)`. See `fusion_emitter_options`."""
    return fusion_emitter_options(_cpu_flag_applied, getattr(env, "unwrapped", env).uses_mjx)


def import_mjx_quietly() -> None:
    """Imports mujoco.mjx (and jax with it) without the "Failed to import warp: ..." lines it prints on stdout
    where warp-lang is not installed: Warp is optional here, and `impl="warp"` names what to install when it is
    asked for. Called first by the packages whose modules import mujoco.mjx or brax (which imports it).

    mujoco loads the GL platform MUJOCO_GL names when it is imported, and fails there when it cannot (osmesa
    without libOSMesa, a misspelt value): that failure is raised as one `GLImportError` ending with `GL_HINT`."""
    import contextlib
    import io

    gl = os.environ.get("MUJOCO_GL")
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import mujoco.mjx  # noqa: F401
    except (RuntimeError, AttributeError, ImportError) as error:
        if not gl:
            raise
        reason = " ".join(f"{type(error).__name__}: {error}".split())
        raise GLImportError(f"mujoco cannot load MUJOCO_GL={gl} ({reason}); {GL_HINT}") from None
    quiet_warp()


def quiet_warp() -> None:
    """Turns Warp's informational lines off where mujoco.mjx imported it, its warnings and errors kept: its start-up
    banner and a line per kernel module loaded, ~40 per process at the first step and again at each new batch size
    (~300 lines in a run of 4 GPUs, 2026-11-28). The kernel preload says in one line what it compiled
    (`jaxarm.envs.panda.warp_kernels`). `warp.config.log_level = warp.LOG_INFO` turns them back on."""
    warp = sys.modules.get("warp")
    if warp is not None and hasattr(warp, "LOG_WARNING"):
        warp.config.log_level = max(warp.config.log_level, warp.LOG_WARNING)
