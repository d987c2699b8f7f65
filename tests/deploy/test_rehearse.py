"""`python -m experiments.rehearse`: an exported sorter policy rehearsed in real time against MuJoCo in its own
process. The episodes' starts come from the env's reset (one MJX program: marked mjx)."""

import contextlib
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from experiments import configs, rehearse
from jaxarm.runner import rundir
from tests.deploy.exported import export_random_policy, sorter_run

STEPS = 10
BUDGET_MS = 60
"""The rehearsals' latency budget here: a loaded CPU delays the robot process's states (p99 83 ms seen in CI), and
past the deadline (a 40 ms control period plus the budget: 60 ms at the default 20 ms budget) the policy ends an
episode early (19 ticks of 20, or before a fault's tick). A 100 ms stall is still past this budget."""


@pytest.mark.mjx
@pytest.mark.slow
def test_the_rehearsal_cli_reports_placements_jitter_and_misses(tmp_path, capsys):
    config = sorter_run(tmp_path, STEPS)
    assert rehearse.main([str(tmp_path)]) == 2
    assert "export the run first" in capsys.readouterr().err
    export_random_policy(tmp_path, config, "24")
    budget = ["--latency-budget", str(BUDGET_MS)]
    assert rehearse.main([str(tmp_path), "--episodes", "2", *budget]) == 0
    result = json.loads((tmp_path / f"rehearse-2-12345-24-{BUDGET_MS}ms.json").read_text())
    assert result["episodes"] == 2 and result["ticks"] == 2 * STEPS and result["faults"] == ["ended", "ended"]
    assert 0.0 <= result["placed_fraction"] <= 1.0 and result["tick_jitter_ms_p99"] >= 0.0
    assert all(np.max(result[f"max_{name}_of_limit"]) <= 1 + 1e-6 for name in ("speed", "acceleration", "jerk"))
    assert "rehearsed in real time" in capsys.readouterr().out
    # A stall: the robot holds and stops, and the episode ends early.
    assert rehearse.main([str(tmp_path), "--episodes", "1", *budget, "--fault", "stall", "--fault-tick", "1"]) == 0
    result = json.loads((tmp_path / f"rehearse-1-12345-24-{BUDGET_MS}ms-stall-tick1.json").read_text())
    assert result["faults"] == ["missed"] and result["ticks"] < STEPS
    # A tick past the episode's end: a fault never injected, reported as none before.
    assert rehearse.main([str(tmp_path), "--episodes", "1", "--fault", "stall", "--fault-tick", str(STEPS)]) == 2
    assert capsys.readouterr().err == f"error: --fault-tick {STEPS}: an episode of the run's env has ticks 0 to 9\n"


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--seed", "99999999999999999999999"], "--seed must fit in int32"),  # JAX's OverflowError before
        (["--latency-budget", "nan"], "--latency-budget must be finite"),  # rehearse-...-nanms.json before
        (["--latency-budget", "-1"], "--latency-budget must be in (0, 20000], got -1.0"),
        (["--latency-budget", "1e300"], "--latency-budget must be in (0, 20000], got 1e+300"),
        (["--fault", "stall", "--fault-tick", "-1"], "a fault's tick counts the policy's ticks from 0, got -1"),
    ],
)
def test_bad_options_are_one_line_before_anything_runs(options, message, tmp_path, capsys):
    assert rehearse.main([str(tmp_path), *options]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {message}") and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


def test_a_camera_policy_is_refused_in_one_line(tmp_path, capsys):
    rundir.write_config(tmp_path, configs.get("ppo_sorter_pixels_dr"), "ppo_sorter_pixels_dr")
    assert rehearse.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"error: {tmp_path}'s policy reads cameras; the rehearsal runs state policies (experiments.transfer runs "
        "camera policies in stock MuJoCo)\n"
    )


def session_processes(session: int) -> list[int]:
    """The processes still running in `session` (Linux's /proc)."""
    alive = []
    for entry in pathlib.Path("/proc").iterdir():
        with contextlib.suppress(ValueError, ProcessLookupError, PermissionError):
            if entry.name.isdigit() and os.getsid(int(entry.name)) == session:
                alive.append(int(entry.name))
    return alive


@pytest.mark.mjx
@pytest.mark.slow
def test_ctrl_c_ends_a_rehearsal_and_its_robot_process_in_one_line(tmp_path):
    export_random_policy(tmp_path, sorter_run(tmp_path, 250), "24")  # 10 s episodes: Ctrl-C comes mid-stream
    command = [sys.executable, "-m", "experiments.rehearse", str(tmp_path), "--episodes", "1"]
    temporary = tmp_path / "tmp"  # where the episode's scene, socket and log go
    temporary.mkdir()
    environ = {**os.environ, "TMPDIR": str(temporary)}
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True, env=environ)
    deadline = time.monotonic() + 120
    while len(session_processes(process.pid)) < 3 and time.monotonic() < deadline:  # it, its tracker, the robot
        time.sleep(0.1)
    assert [path.name[: len("rehearse-")] for path in temporary.iterdir()] == ["rehearse-"]
    time.sleep(1.0)
    os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C reaches every process of its group
    _, err = process.communicate(timeout=60)
    # The robot printed its own KeyboardInterrupt traceback, and lived on 20 s where it had not connected yet.
    assert process.returncode == 130
    assert err == "\ninterrupted and ended at once; run the command again for its results\n", err[-3000:]
    deadline = time.monotonic() + 30  # the robot may still be importing, on a loaded CPU
    while session_processes(process.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert session_processes(process.pid) == []
    assert list(temporary.iterdir()) == []  # the robot wrote its log there after the rehearsal had gone


def test_a_temporary_directory_too_deep_for_the_robots_socket_is_one_line_before_anything_is_written(tmp_path):
    # Before: zmq's "File name too long" traceback, then the robot's own, its scene removed under it.
    deep = tmp_path / ("t" * 110) / "rehearse-x"
    deep.mkdir(parents=True)
    with pytest.raises(ValueError, match=r"^the robot's socket .*/robot.ipc is longer than a socket's path may be"):
        rehearse.driver_setup(None, None, None, deep, None)
    assert list(deep.iterdir()) == []
