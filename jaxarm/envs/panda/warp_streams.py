"""Warp's registrations of the CUDA streams it does not own, counted per stream.

Each Warp call inside a JAX program (MJX's Warp FFI) wraps JAX's CUDA stream in a new `wp.Stream(device,
cuda_stream=handle)`, which registers the handle in Warp's native map of streams, and the wrapper's finaliser
erases it, with no count (warp-lang 1.19, `cuda_stream_register` / `cuda_stream_unregister`). A wrapper finalised
after a newer one has registered the same handle (collected late from a reference cycle, or on another thread)
leaves the newer one's graph capture on a stream Warp no longer knows: `RuntimeError: Warp error: unknown stream`
at the first chunk of one fresh `ppo_sorter` run in 12 (H200, 2026-11-28, BENCHMARKS.md#sorter). Counted, the
handle is registered by its first live wrapper and erased with its last; every registration after the first also
no longer makes (and leaks) a CUDA event. Only wrappers of foreign streams go through these two entry points:
streams Warp creates register and erase themselves in native code.
"""

import threading
from collections.abc import Callable
from typing import Any

Registration = Callable[[Any, Any], None]
"""`wp_cuda_stream_register` or `_unregister` of Warp's native library: (CUDA context, stream handle) -> None."""


def counted(register: Registration, unregister: Registration) -> tuple[Registration, Registration]:
    """(register, unregister) that call the given ones only when a handle's count of live wrappers goes from 0 to 1
    and from 1 to 0; safe to call from several threads."""
    lock = threading.Lock()
    live: dict[Any, int] = {}  # by stream handle, which names one stream of one context

    def counted_register(context: Any, stream: Any) -> None:
        with lock:
            live[stream] = live.get(stream, 0) + 1
            if live[stream] == 1:
                register(context, stream)

    def counted_unregister(context: Any, stream: Any) -> None:
        with lock:
            count = live.pop(stream, 0)
            if count > 1:
                live[stream] = count - 1
                return
            unregister(context, stream)

    return counted_register, counted_unregister


_INSTALLED = threading.Lock()


def count_foreign_stream_wrappers() -> None:
    """Routes Warp's registrations of foreign streams through `counted`, once per process (Warp initialised)."""
    import warp as wp
    from warp._src import context  # private: warp-lang is pinned in constraints.txt

    wp.init()
    core = context.runtime.core
    with _INSTALLED:
        if getattr(core, "jaxarm_counted_streams", False):
            return
        core.wp_cuda_stream_register, core.wp_cuda_stream_unregister = counted(
            core.wp_cuda_stream_register, core.wp_cuda_stream_unregister
        )
        core.jaxarm_counted_streams = True
