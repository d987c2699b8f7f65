"""Counted registrations of foreign CUDA streams (`jaxarm.envs.panda.warp_streams`), on fakes of Warp's native pair."""

import threading

import pytest

from jaxarm.envs.panda.warp_streams import count_foreign_stream_wrappers, counted


def registry_and_counted():
    registered: dict[int, int] = {}  # handle -> how many native registrations it holds (Warp's map: 0 or 1)

    def register(context, stream):
        registered[stream] = 1

    def unregister(context, stream):
        registered.pop(stream, None)

    return registered, *counted(register, unregister)


def test_a_wrapper_finalised_late_leaves_the_newer_ones_stream_registered():
    registered, register, unregister = registry_and_counted()
    register("ctx", 7)  # the wrapper of one FFI call
    register("ctx", 7)  # the next call's, before the first is finalised
    unregister("ctx", 7)  # the first, collected late
    assert registered == {7: 1}
    unregister("ctx", 7)
    assert registered == {}


def test_streams_are_counted_apart_and_an_unknown_one_unregisters_as_before():
    registered, register, unregister = registry_and_counted()
    register("ctx", 1)
    register("ctx", 2)
    unregister("ctx", 1)
    assert registered == {2: 1}
    unregister("ctx", 3)  # registered before the counting began: erased as Warp would
    assert registered == {2: 1}


def test_wrappers_on_several_threads_balance():
    calls: list[str] = []
    register, unregister = counted(lambda c, s: calls.append("register"), lambda c, s: calls.append("unregister"))

    def wrap_many():
        for _ in range(2000):
            register("ctx", 5)
            unregister("ctx", 5)

    threads = [threading.Thread(target=wrap_many) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    # Native calls alternate, starting with a registration: never an erase while a wrapper lives.
    assert calls[0] == "register" and calls[-1] == "unregister"
    assert all(a != b for a, b in zip(calls, calls[1:], strict=False))


def test_warps_pair_is_wrapped_once_per_process():
    pytest.importorskip("warp")
    from warp._src import context

    count_foreign_stream_wrappers()
    wrapped = context.runtime.core.wp_cuda_stream_register
    count_foreign_stream_wrappers()
    assert context.runtime.core.wp_cuda_stream_register is wrapped
    assert wrapped.__name__ == "counted_register"
