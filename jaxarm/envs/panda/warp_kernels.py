"""MuJoCo Warp's kernels for a scene compiled in parallel, ahead of its first Warp step.

Warp compiles a module of kernels (one NVRTC call on a GPU) the first time one of its kernels launches, and
MuJoCo Warp makes many of its kernels while it steps (builders specialise them to the model's geoms and
options). So the first physics step on a machine with an empty kernel cache compiles ~40 modules one after
another on one core: ~60 s of the sorter's first step on a fresh H200 host with warp-lang 1.19 (2026-11-28;
178 s with 1.18 on another). `start_preload` finds the modules a scene's step launches by running MuJoCo Warp's step
once on a one-world copy of the scene on the CPU with its launches recorded instead of run (about a second), then
compiles them for the GPU on a thread per core, on a background thread, while XLA compiles the program that will
step them.
They go to Warp's on-disk kernel cache, where the step's own first launch finds them and loads them in
milliseconds (as every later process does).

The background thread only compiles: it never touches the GPU. Loading a module into the CUDA context from
another thread while MJX captures the step's CUDA graph invalidates the capture ("Graph creation error ...
invalid argument", H200, 2026-11-28), and so would the device arrays of a one-world copy on the GPU. A module the
step reaches while the preload still compiles it is compiled twice (Warp builds in a directory of its own per
thread and moves the result into place), which costs time but cannot give a wrong kernel; one the CPU's record
missed (a few kernels are chosen per device) is compiled at its first launch, as without the preload.
"""

import concurrent.futures
import contextlib
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator

import mujoco
import warp as wp
from mujoco.mjx.third_party import mujoco_warp

_RECORDING = threading.local()
_PATCH_LOCK = threading.Lock()
_STARTED: dict[tuple[str, int], threading.Thread] = {}
"""The preloads this process has started, by device (its Warp alias, e.g. "cuda:0") and scene (its MjModel's id)."""
_RESULTS: dict[tuple[str, int], tuple[int, float]] = {}
"""What each finished preload compiled: (modules, seconds)."""


Variant = tuple[wp.Module, int | None]
"""A kernel module and the block size a launch asked for (None: Warp's default)."""


def _recordable(launch: Callable) -> Callable:
    """`launch` (wp.launch or wp.launch_tiled), which on a thread that is recording adds the kernel's module and
    block size to that thread's record and runs nothing."""

    def maybe_record(kernel, *args, **kwargs):
        record = getattr(_RECORDING, "variants", None)
        if record is None:
            return launch(kernel, *args, **kwargs)
        record.add((kernel.module, kwargs.get("block_dim")))
        return None

    maybe_record.__wrapped__ = launch  # type: ignore[attr-defined]
    return maybe_record


def _install_recorders() -> None:
    """Wraps wp.launch and wp.launch_tiled once per process (other threads' launches run as before)."""
    with _PATCH_LOCK:
        for name in ("launch", "launch_tiled"):
            launch = getattr(wp, name)
            if not hasattr(launch, "__wrapped__"):
                setattr(wp, name, _recordable(launch))


@contextlib.contextmanager
def _recording() -> Iterator[set[Variant]]:
    _install_recorders()
    variants: set[Variant] = set()
    _RECORDING.variants = variants
    try:
        yield variants
    finally:
        _RECORDING.variants = None


def step_variants(mj_model: mujoco.MjModel) -> set[Variant]:
    """The kernel modules and block sizes one MuJoCo Warp step of `mj_model` launches, recorded on the CPU with
    the options the Panda scenes step with (`mjx_impl.put_scene`: no graph conditionals, no overflow warnings)."""
    with wp.ScopedDevice("cpu"):
        model = mujoco_warp.put_model(mj_model)
        model.opt.graph_conditional = False
        model.opt.warn_overflow = 0
        data = mujoco_warp.make_data(mj_model, nworld=1)
        with _recording() as variants:
            mujoco_warp.step(model, data)
    return variants


def _compile(variant: Variant, device: wp.Device) -> bool:
    """Compiles one variant for the GPU `device` into the kernel cache, under the name `Module.load` looks for,
    without loading it (Warp's public `compile_aot_module` compiles the module's default block size only); False
    where the cache held it already."""
    module, asked = variant
    # A CPU launch asks for one thread per block where the GPU's asks for the default: compile the GPU's.
    block_dim = asked if asked is not None and asked > 1 else module.options["block_dim"]
    module.get_module_hash(block_dim)  # resolves the variant's options
    # Warp's own build step, as Module.load calls it (private: warp-lang is pinned in constraints.txt).
    return module._compile(
        device,
        os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier(block_dim)),
        module._get_compile_output_name(device, block_dim=block_dim),
        module._get_compile_arch(device),
        options=module.resolved_options[block_dim],
    )


def compile_variants(variants: set[Variant], device: str, workers: int) -> int:
    """Compiles `variants` for `device`, `workers` at a time (NVRTC releases the GIL); how many compiled (not those
    the cache held; a variant that fails is left to its first launch, which reports the error)."""
    target = wp.get_device(device)

    def compiled(variant: Variant) -> bool:
        try:
            return _compile(variant, target)
        except Exception:
            return False

    with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
        return sum(pool.map(compiled, variants))


def _compile_into(key: tuple[str, int], variants: set[Variant], device: str) -> None:
    # A failure here is only a lost head start: the step compiles what it needs, and reports its own errors.
    began, workers = time.perf_counter(), len(os.sched_getaffinity(0))
    with contextlib.suppress(Exception):
        compiled = compile_variants(variants, device, workers)
        seconds = time.perf_counter() - began
        _RESULTS[key] = compiled, seconds
        if compiled:  # Warp's own line per module is off (jaxarm._runtime.quiet_warp): one line for them all
            print(
                f"Warp: compiled {compiled} of the scene's {len(variants)} kernel modules for {device} in "
                f"{seconds:.0f} s on {workers} threads, into {wp.config.kernel_cache_dir}",
                file=sys.stderr,
                flush=True,
            )


def start_preload(mj_model: mujoco.MjModel, device: str) -> None:
    """Records what one Warp step of `mj_model` launches, here (about a second), then compiles it for `device` on a
    background (daemon) thread; once per scene and device per process.

    The record runs on the calling thread because it makes the CPU Warp's default device for its length, and that
    default is one for the whole process: on a thread of its own it could meet, and undo, a scope of the caller's.
    """
    key = (device, id(mj_model))
    if key in _STARTED:
        return
    try:
        variants = step_variants(mj_model)
    except Exception:  # as in _compile_into: the step compiles what it needs
        return
    thread = threading.Thread(target=_compile_into, args=(key, variants, device), name="warp-preload", daemon=True)
    _STARTED[key] = thread
    thread.start()


def finish_preloads() -> list[tuple[int, float] | None]:
    """Waits for every preload this process started; each one's (modules compiled, seconds), None where its
    compile failed."""
    for thread in _STARTED.values():
        thread.join()
    return [_RESULTS.get(key) for key in _STARTED]
