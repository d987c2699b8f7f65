"""The tests of commands run as several processes, optionally on a loaded CPU.

`JAXARM_TEST_LOAD=1 pytest tests/experiments/test_distributed.py` runs each test that asks for `loaded_cpu` with
one busy-looping process per core beside it: processes of one job then start, compile and reach their
collectives far apart, as on a machine shared with other work, where a sweep of two processes once failed that
passed on a quiet one.
"""

import os
import subprocess
import sys

import pytest

LOAD_VARIABLE = "JAXARM_TEST_LOAD"


@pytest.fixture
def loaded_cpu():
    """One busy-looping process per core for the test's duration where JAXARM_TEST_LOAD is set (not "0");
    nothing otherwise."""
    if os.environ.get(LOAD_VARIABLE, "0") in ("", "0"):
        yield
        return
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(os.cpu_count() or 1)]
    try:
        yield
    finally:
        for process in busy:
            process.kill()
            process.wait()
