"""Runs of two processes (`--distributed`, JAX's CPU collectives over gloo) compute what one process computes, and
a run checkpointed by two processes resumes on one and the reverse; a sweep shared out over devices computes what
one device does."""

import csv
import os
import socket
import subprocess
import sys
import textwrap
import time

import jax
import numpy as np
import pytest

from experiments import distributed
from jaxarm.runner import load_run, read_metrics

OVERRIDES = [
    "num_envs=16",
    "rollout_length=8",
    "num_minibatches=2",
    "num_epochs=2",
    "total_env_steps=1024",
    "updates_per_chunk=2",
    "eval_episodes=16",
    "policy_hidden_sizes=16",
    "value_hidden_sizes=16",
]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def run_processes(count: int, args: list[str], first_only: list[str] = ()) -> list[subprocess.CompletedProcess]:
    """Runs `experiments.run ARGS` as `count` processes of one run (each with one CPU device); `first_only`
    arguments go to process 0 alone."""
    command = [sys.executable, "-m", "experiments.run", *args]
    if count == 1:
        return [subprocess.run(command, capture_output=True, text=True, timeout=600)]
    joining = ["--distributed", "--coordinator", f"127.0.0.1:{free_port()}", "--num-processes", str(count)]
    children = [
        subprocess.Popen(
            [*command, *joining, "--process-id", str(index), *(first_only if index == 0 else [])],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for index in range(count)
    ]
    results = []
    for child in children:
        out, err = child.communicate(timeout=600)
        results.append(subprocess.CompletedProcess(child.args, child.returncode, out, err))
    return results


def assert_codes(results: list[subprocess.CompletedProcess], code: int) -> None:
    for result in results:
        assert result.returncode == code, result.stderr[-3000:]


def params_gap(run_a, run_b) -> float:
    (_, a), (_, b) = load_run(run_a), load_run(run_b)
    return max(
        float(np.max(np.abs(np.asarray(x) - np.asarray(y))))
        for x, y in zip(jax.tree.leaves(a.params), jax.tree.leaves(b.params), strict=True)
    )


@pytest.mark.slow
def test_two_processes_compute_one_process_run_and_resume_across(tmp_path):
    one = tmp_path / "one"
    assert_codes(run_processes(1, ["--config", "ppo_arm2d", "--out", str(one), *OVERRIDES]), 0)

    # Two processes, stopped after their first chunk by process 0's time limit alone: both stop there together.
    two_then_one = tmp_path / "two_then_one"
    stop_first = ["--stop-after-minutes", "0"]
    results = run_processes(2, ["--config", "ppo_arm2d", "--out", str(two_then_one), *OVERRIDES], stop_first)
    assert_codes(results, 0)
    assert "success_rate" in results[0].stdout and "success_rate" not in results[1].stdout  # process 0 reports
    assert [row["updates"] for row in read_metrics(two_then_one)] == [1, 2]  # written once, by process 0
    assert_codes(run_processes(1, ["--resume", str(two_then_one)]), 0)

    one_then_two = tmp_path / "one_then_two"
    assert_codes(run_processes(1, ["--config", "ppo_arm2d", "--out", str(one_then_two), *OVERRIDES, *stop_first]), 0)
    # Resumed by two processes that the command starts itself (one GPU each on a GPU host).
    assert_codes(run_processes(1, ["--resume", str(one_then_two), "--local-processes", "2"]), 0)

    updates = [row["updates"] for row in read_metrics(one)]
    for run in (two_then_one, one_then_two):
        assert [row["updates"] for row in read_metrics(run)] == updates
        # Identical up to the order in which the devices' gradients are summed.
        assert params_gap(one, run) < 1e-4


def test_distributed_without_its_processes_is_one_line(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d", "--distributed", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1].startswith("error: --distributed could not join")


def test_local_processes_are_checked_and_leave_the_children_their_arguments(monkeypatch):
    assert distributed.without_local_processes(["--resume", "r", "--local-processes", "2", "x=1"]) == [
        "--resume",
        "r",
        "x=1",
    ]
    assert distributed.without_local_processes(["--local-processes=4", "--out", "o"]) == ["--out", "o"]
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "3,5")
    assert distributed.local_gpus(2) == ["3", "5"]
    with pytest.raises(ValueError, match="names only 2"):
        distributed.local_gpus(4)
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d", "--local-processes", "2", "--distributed"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and "--local-processes takes a count of 1 or more" in result.stderr


def sweep_results(out, device_count: int, stopped: bool = False) -> list[dict]:
    """results.csv of a 2-value × 2-seed ppo_arm2d sweep run on `device_count` forced host devices (`stopped`:
    checkpointed after its first chunk, then resumed)."""
    command = [sys.executable, "-m", "experiments.sweep", "--config", "ppo_arm2d", "--seeds", "2", "--out", str(out)]
    command += [*OVERRIDES[:6], "eval_episodes=16", "learning_rate=3e-4,1e-3"]
    commands = [[*command, "--stop-after-minutes", "0"], command[:3] + ["--resume", str(out)]] if stopped else [command]
    env = {**os.environ, "XLA_FLAGS": f"--xla_force_host_platform_device_count={device_count}"}
    for each in commands:
        result = subprocess.run(each, capture_output=True, text=True, timeout=600, env=env)
        assert result.returncode == 0, result.stderr[-3000:]
    assert (f"4 runs shared over {device_count} devices" in result.stdout) == (device_count > 1)
    with (out / "results.csv").open() as handle:
        return [{key: value for key, value in row.items() if key != "group_wall_s"} for row in csv.DictReader(handle)]


@pytest.mark.slow
def test_a_sweep_shared_over_devices_computes_what_one_device_does(tmp_path):
    one, four = sweep_results(tmp_path / "one", 1), sweep_results(tmp_path / "four", 4)
    assert sweep_results(tmp_path / "resumed", 4, stopped=True) == four  # its members restored onto their devices
    assert [row["setting"] for row in one] == [row["setting"] for row in four]
    for single, shared in zip(one, four, strict=True):
        for column in ("success_mean", "return_mean", "return_std"):
            assert float(shared[column]) == pytest.approx(float(single[column]), abs=1e-4)


SORTER_START = textwrap.dedent("""
    import sys, jax
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=sys.argv[1], num_processes=2, process_id=int(sys.argv[2]))
    from experiments import configs
    from jaxarm.agents.common.config import apply_overrides
    from jaxarm.agents.common.sharding import data_mesh, envs_split_over
    from jaxarm.runner import rundir

    overrides = ["env_kwargs.impl=jax", "num_envs=16", "rollout_length=8", "num_minibatches=2"]
    config = apply_overrides(configs.get("ppo_sorter"), overrides)
    with envs_split_over(data_mesh()):
        trainer = rundir.make_trainer(config)
        # Lowering embeds every array the program closes over: one on another process's device fails here.
        jax.jit(trainer.init).lower(jax.random.PRNGKey(0), config.hparams())
    print("lowered")
""")


@pytest.mark.slow
def test_every_process_of_a_sorter_run_holds_its_own_mjx_model(tmp_path):
    # MJX puts a model on jax.devices()[0] unless told: process 0's device, which process 1 cannot close over.
    coordinator = f"127.0.0.1:{free_port()}"
    children = [
        subprocess.Popen(
            [sys.executable, "-c", SORTER_START, coordinator, str(index)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "JAX_PLATFORMS": "cpu"},
        )
        for index in range(2)
    ]
    for child in children:
        out, err = child.communicate(timeout=600)
        assert child.returncode == 0 and "lowered" in out, err[-3000:]


ONE_FAILS = textwrap.dedent("""
    import pathlib, signal, sys, time
    process = sys.argv[sys.argv.index("--process-id") + 1]
    if process == "1":
        sys.exit(3)  # as a process that died
    def stopped(signum, frame):
        pathlib.Path(sys.argv[1]).write_text("stopped")
        sys.exit(0)
    signal.signal(signal.SIGTERM, stopped)
    time.sleep(120)
""")


def test_where_one_local_process_fails_the_launcher_stops_the_others(tmp_path, monkeypatch):
    (tmp_path / "one_fails.py").write_text(ONE_FAILS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    marker = tmp_path / "process0"
    start = time.monotonic()
    assert distributed.spawn("one_fails", [str(marker)], 2) == 3  # the failed process's code
    assert marker.read_text() == "stopped"  # process 0 was told to stop (SIGTERM), not left waiting for its peer
    assert time.monotonic() - start < distributed.STOP_GRACE_S
