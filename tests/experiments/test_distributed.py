"""Runs of two processes (`--distributed`, JAX's CPU collectives over gloo) compute what one process computes, and
a run checkpointed by two processes resumes on one and the reverse; a sweep shared out over devices computes what
one device does."""

import argparse
import csv
import io
import os
import pathlib
import signal
import socket
import subprocess
import sys
import textwrap
import time

import jax
import numpy as np
import pytest

from experiments import configs, distributed, run, sweep
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import apply_overrides
from jaxarm.exits import STOPPED_BY_SIGNAL
from jaxarm.runner import load_run, progress, read_metrics, rundir
from tests.experiments.test_rundir import assert_same_learner

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


def start_processes(count: int, args: list[str], first_only: list[str] = ()) -> list[subprocess.Popen]:
    """Starts `experiments.run ARGS` as `count` processes of one run joined by `--distributed` (each with one CPU
    device); `first_only` arguments go to process 0 alone."""
    command = [sys.executable, "-m", "experiments.run", *args]
    joining = ["--distributed", "--coordinator", f"127.0.0.1:{free_port()}", "--num-processes", str(count)]
    return [
        subprocess.Popen(
            [*command, *joining, "--process-id", str(index), *(first_only if index == 0 else [])],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for index in range(count)
    ]


def run_processes(count: int, args: list[str], first_only: list[str] = ()) -> list[subprocess.CompletedProcess]:
    """Runs `experiments.run ARGS` as `count` processes of one run (each with one CPU device); `first_only`
    arguments go to process 0 alone."""
    if count == 1:
        command = [sys.executable, "-m", "experiments.run", *args]
        return [subprocess.run(command, capture_output=True, text=True, timeout=600)]
    results = []
    for child in start_processes(count, args, first_only):
        out, err = child.communicate(timeout=600)
        results.append(subprocess.CompletedProcess(child.args, child.returncode, out, err))
    return results


def assert_codes(results: list[subprocess.CompletedProcess], code: int) -> None:
    for result in results:
        assert result.returncode == code, result.stderr[-3000:]


NOISE = ("Traceback", "[Gloo]", "WatchTasksAsync", "coordination service", "Check failure")
"""Words of what JAX, gloo and gRPC print where processes do not start or end cleanly."""


def assert_quiet(result: subprocess.CompletedProcess) -> None:
    """Fails where `result`'s output holds any of NOISE: a clean start and finish of several processes print none."""
    for words in NOISE:
        assert words not in result.stdout + result.stderr, result.stdout[-3000:] + result.stderr[-3000:]


def params_gap(run_a, run_b) -> float:
    (_, a), (_, b) = load_run(run_a), load_run(run_b)
    return max(
        float(np.max(np.abs(np.asarray(x) - np.asarray(y))))
        for x, y in zip(jax.tree.leaves(a.params), jax.tree.leaves(b.params), strict=True)
    )


@pytest.mark.slow
@pytest.mark.usefixtures("loaded_cpu")
def test_two_processes_compute_one_process_run_and_resume_across(tmp_path):
    one = tmp_path / "one"
    assert_codes(run_processes(1, ["--config", "ppo_arm2d", "--out", str(one), *OVERRIDES]), 0)

    # Two processes, stopped after their first chunk by process 0's time limit alone: both stop there together.
    two_then_one = tmp_path / "two_then_one"
    stop_first = ["--stop-after-minutes", "0"]
    results = run_processes(2, ["--config", "ppo_arm2d", "--out", str(two_then_one), *OVERRIDES], stop_first)
    assert_codes(results, 0)
    for result in results:
        assert_quiet(result)
    assert "success_rate" in results[0].stdout and "success_rate" not in results[1].stdout  # process 0 reports
    assert [row["updates"] for row in read_metrics(two_then_one)] == [1, 2]  # written once, by process 0
    assert_codes(run_processes(1, ["--resume", str(two_then_one)]), 0)

    one_then_two = tmp_path / "one_then_two"
    assert_codes(run_processes(1, ["--config", "ppo_arm2d", "--out", str(one_then_two), *OVERRIDES, *stop_first]), 0)
    # Resumed by two processes that the command starts itself (one GPU each on a GPU host).
    assert_codes(run_processes(1, ["--resume", str(one_then_two), "--local-processes", "2"]), 0)

    updates = [row["updates"] for row in read_metrics(one)]
    for resumed in (two_then_one, one_then_two):
        assert [row["updates"] for row in read_metrics(resumed)] == updates
        # Identical up to the order in which the devices' gradients are summed.
        assert params_gap(one, resumed) < 1e-4


def test_distributed_without_its_processes_is_one_line(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d", "--distributed", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1].startswith("error: --distributed could not join")


@pytest.mark.parametrize("index", [0, 1])
def test_a_process_whose_peers_never_join_ends_in_one_line_at_its_join_timeout(tmp_path, index):
    coordinator = f"127.0.0.1:{free_port()}"
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d", "--out", str(tmp_path / "run")]
        + ["--distributed", "--coordinator", coordinator, "--num-processes", "2", "--process-id", str(index)]
        + ["--join-timeout", "2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"error: --distributed: not every process joined within 2 s (process {index} of 2, coordinator "
        f"{coordinator}, nothing trained); start the same command in each process, or give --join-timeout more seconds"
    ]
    assert not (tmp_path / "run").exists()


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
    for entry in (run, sweep):  # 100000 forked ~2,600 JAX processes before: refused before any fork
        with pytest.raises(SystemExit) as exited:
            entry.parse_args(["--config", "ppo_arm2d", "--local-processes", "100000"])
        assert exited.value.code == 2


@pytest.mark.usefixtures("loaded_cpu")
def test_non_dividing_num_envs_stop_local_processes_with_one_clear_error(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d", "--local-processes", "2"]
        + ["--out", str(tmp_path / "run"), *OVERRIDES[2:], "num_envs=9"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 2
    # Each process says it in its own words: none is aborted by JAX as process 0, gone first, takes its service.
    error = "error: num_envs=9 must divide by the 2 devices it is split over"
    assert result.stderr.splitlines().count(error) == 2, result.stderr[-3000:]
    assert_quiet(result)


def test_a_peer_jax_aborts_after_a_reported_error_leaves_that_error_as_the_failure():
    # Process 0 refused the config and left first; JAX aborted process 1 (SIGABRT) as its service went with it.
    assert distributed._failure([10, 11], {10: distributed.REPORTED_ERROR, 11: -signal.SIGABRT}, "RESUME") == (2, None)
    # A process killed from outside is named, whatever its peers reported after.
    code, line = distributed._failure([10, 11], {10: 1, 11: -signal.SIGKILL}, "RESUME")
    assert code == 128 + signal.SIGKILL
    assert line == "error: process 1 (pid 11) was killed by SIGKILL; the others are told to stop; continue with: RESUME"


H100 = "GPU {index}: NVIDIA H100 80GB HBM3 (UUID: GPU-{index}b4f-0e1c)"
MIG = "  MIG 3g.40gb     Device  0: (UUID: MIG-9d1e-7a41)"


def test_gpus_are_counted_from_nvidia_smi_as_cuda_visible_devices_and_jax_platforms_allow():
    listing = "\n".join(H100.format(index=index) for index in range(4)) + "\n"
    assert distributed.listed_gpus(listing) == 4
    assert distributed.listed_gpus(f"{H100.format(index=0)}\n{MIG}\n") == 1  # a MIG instance under its GPU
    assert distributed.listed_gpus("") == 0  # no nvidia-smi, or it failed
    visible = {
        None: 4,
        "": 0,
        "2,3": 2,
        " 1 , 3 ": 2,
        "0,1,2,3,4,5": 4,  # CUDA stops at the first index that does not exist
        "-1": 0,
        "1,-1,2": 1,
        "GPU-0b4f-0e1c,GPU-1b4f-0e1c": 2,
    }
    for cuda_visible_devices, count in visible.items():
        assert distributed.visible_gpus(4, cuda_visible_devices, None) == count, cuda_visible_devices
    assert distributed.visible_gpus(0, "0,1", None) == 0
    assert distributed.visible_gpus(4, None, "cpu") == 0
    assert distributed.visible_gpus(4, "0,1", "cuda,cpu") == 2
    assert distributed.visible_gpus(4, None, "") == 4


def test_gpus_here_asks_nvidia_smi_and_counts_none_where_it_is_missing_or_fails(tmp_path, monkeypatch):
    monkeypatch.delenv("JAX_PLATFORMS", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "1,2")
    assert distributed.gpus_here() == 0  # no nvidia-smi
    tool = tmp_path / "nvidia-smi"
    lines = "\n".join(H100.format(index=index) for index in range(4))
    tool.write_text(f'#!/bin/sh\n[ "$1" = "-L" ] && printf "{lines}\\n"\n')
    tool.chmod(0o755)
    assert distributed.gpus_here() == 2
    tool.write_text("#!/bin/sh\necho 'NVIDIA-SMI has failed'; exit 9\n")
    assert distributed.gpus_here() == 0


@pytest.mark.parametrize(
    ("impl", "warp_installed", "on_warp"),
    [("warp", True, True), ("auto", True, True), ("auto", False, False), ("jax", True, False), (None, True, False)],
)
def test_an_env_steps_warp_where_asked_or_left_to_auto_with_warp_installed(impl, warp_installed, on_warp):
    env_kwargs = {} if impl is None else {"impl": impl, "max_envs": 8192}  # None: an env without MJX
    assert distributed.steps_on_warp(env_kwargs, warp_installed) is on_warp


@pytest.mark.parametrize(
    ("given", "joined", "spreads", "gpus", "count"),
    [
        (None, False, True, 4, 4),
        (None, False, False, 4, 1),
        (None, False, True, 1, 1),
        (None, False, True, 0, 1),
        (1, False, True, 4, 1),  # the opt-out
        (2, False, False, 4, 2),
        (None, True, True, 4, 1),  # one of several already
    ],
)
def test_a_run_that_spreads_starts_one_process_per_gpu_unless_told(given, joined, spreads, gpus, count):
    assert distributed.local_process_count(given, joined, spreads, gpus) == count


@pytest.fixture
def started(monkeypatch, tmp_path):
    """The processes `run` would start on a host of 4 GPUs with warp-lang, as (main, argv, count), none started;
    building an env (which would start JAX's backend on every GPU) fails the test."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(distributed, "gpus_here", lambda: 4)
    monkeypatch.setattr(run, "warp_available", lambda: True)
    calls = []
    monkeypatch.setattr(distributed, "spawn", lambda main, argv, count, *_: calls.append((main, argv, count)) or 0)

    def no_backend(*args, **kwargs):
        raise AssertionError("the launching process asked JAX for its devices")

    monkeypatch.setattr(jax, "devices", no_backend)
    return calls


def test_a_warp_run_hands_its_processes_one_run_directory(started, tmp_path, capsys):
    assert run._main(["--config", "ppo_sorter", "num_envs=64"]) == 0
    (run_dir,) = (tmp_path / "runs").iterdir()  # named as a run of one process names it
    assert run_dir.name.startswith("ppo_sorter-")
    out = str(pathlib.Path("runs") / run_dir.name)
    assert started.pop() == (run.main, ["--out", out, "--config", "ppo_sorter", "num_envs=64"], 4)
    told = "one process each (faster than one process driving them all; --local-processes 1 for that)"
    assert capsys.readouterr().out == f"{out}: MJX Warp on 4 GPUs, {told}\n"

    given = ["--config", "ppo_sorter", "--out", "mine", "--local-processes", "2"]
    assert run._main(given) == 0
    assert started.pop() == (run.main, given, 2) and capsys.readouterr().out == ""

    saved = tmp_path / "saved"
    rundir.write_config(saved, configs.get("ppo_sorter", validate=False), "ppo_sorter")
    assert run._main(["--resume", str(saved), "total_env_steps=1000000"]) == 0
    assert started.pop() == (run.main, ["--resume", str(saved), "total_env_steps=1000000"], 4)


def test_overrides_and_saved_configs_decide_the_engine_without_building_it(started, tmp_path):
    planned = run.planned_config(run.parse_args(["--config", "ppo_sorter", "env_kwargs.impl=jax"]))
    assert dict(planned.env_kwargs)["impl"] == "jax"
    saved = tmp_path / "saved"
    rundir.write_config(saved, planned, "ppo_sorter")
    assert dict(run.planned_config(run.parse_args(["--resume", str(saved)])).env_kwargs)["impl"] == "jax"
    assert run.local_processes(run.parse_args(["--resume", str(saved)])) == 1
    assert run.local_processes(run.parse_args(["--config", "ppo_sorter"])) == 4
    assert run.local_processes(run.parse_args(["--config", "ppo_arm2d"])) == 1
    # Learners not yet run as several processes stay one unless told.
    assert run.local_processes(run.parse_args(["--config", "td3_sorter"])) == 1
    assert run.local_processes(run.parse_args(["--config", "ppo_sorter_pixels"])) == 1
    assert run.local_processes(run.parse_args(["--config", "td3_sorter", "--local-processes", "2"])) == 2


def test_a_sweep_over_local_processes_starts_them_on_one_directory(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    started = []
    monkeypatch.setattr(distributed, "spawn", lambda main, argv, count, *_: started.append((main, argv, count)) or 0)
    asked = ["--config", "ppo_arm2d", "--seeds", "2", "--local-processes", "2", "learning_rate=3e-4,1e-3"]
    assert sweep.main(asked) == 0
    (out,) = (tmp_path / "runs").iterdir()
    assert out.name.startswith("sweep-ppo_arm2d-")
    assert started == [(sweep.main, ["--out", str(pathlib.Path("runs") / out.name), *asked], 2)]
    assert sweep.main(["--resume", "stopped", "--local-processes", "2"]) == 0
    assert started[-1] == (sweep.main, ["--resume", "stopped", "--local-processes", "2"], 2)


def test_only_the_primary_process_prints_a_sweeps_progress(tmp_path, capsys):
    # Each process of a distributed sweep runs `sweep` alike: the console had every line once per process.
    # (The primary's lines: test_faults' sweeps.) One update of the smallest run: the compiling takes the time.
    base = apply_overrides(configs.get("ppo_arm2d_fixed"), [*OVERRIDES, "total_env_steps=128", "eval_episodes=2"])
    sweep.sweep(base, sweep.parse_grid(base, []), 1, tmp_path, "other", primary=False)
    assert capsys.readouterr().out == ""


def sweep_results(out, device_count: int, stopped: bool = False, processes: int = 1) -> list[dict]:
    """results.csv of a 2-value × 2-seed ppo_arm2d sweep run on `device_count` forced host devices per process, in
    `processes` processes (`stopped`: checkpointed after its first chunk, then resumed)."""
    command = [sys.executable, "-m", "experiments.sweep", "--config", "ppo_arm2d", "--seeds", "2", "--out", str(out)]
    command += ["--local-processes", str(processes)]
    command += [*OVERRIDES[:6], "eval_episodes=16", "learning_rate=3e-4,1e-3"]
    commands = [[*command, "--stop-after-minutes", "0"], command[:3] + ["--resume", str(out)]] if stopped else [command]
    env = {**os.environ, "XLA_FLAGS": f"--xla_force_host_platform_device_count={device_count}"}
    for each in commands:
        result = subprocess.run(each, capture_output=True, text=True, timeout=600, env=env)
        assert result.returncode == 0, result.stderr[-3000:]
        assert_quiet(result)
        assert result.stderr.count(progress.GSPMD_NOTE) == (device_count * processes > 1), result.stderr[-3000:]
    assert (f"4 runs shared over {device_count * processes} devices" in result.stdout) == (device_count * processes > 1)
    with (out / "results.csv").open() as handle:
        return [{key: value for key, value in row.items() if key != "group_wall_s"} for row in csv.DictReader(handle)]


@pytest.mark.slow
@pytest.mark.usefixtures("loaded_cpu")
def test_a_sweep_shared_over_devices_computes_what_one_device_does(tmp_path):
    one, four = sweep_results(tmp_path / "one", 1), sweep_results(tmp_path / "four", 4)
    assert sweep_results(tmp_path / "resumed", 4, stopped=True) == four  # its members restored onto their devices
    two_processes = sweep_results(tmp_path / "two", 1, processes=2)
    for shared_out in (four, two_processes):
        assert [row["setting"] for row in one] == [row["setting"] for row in shared_out]
        for single, shared in zip(one, shared_out, strict=True):
            for column in ("success_mean", "success_min", "return_mean", "return_std"):
                assert float(shared[column]) == pytest.approx(float(single[column]), abs=1e-4)


SORTER_START = textwrap.dedent("""
    import sys, jax
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=sys.argv[1], num_processes=2, process_id=int(sys.argv[2]))
    from experiments import configs
    from jaxarm.agents.common import checkpoint
    from jaxarm.agents.common.config import apply_overrides
    from jaxarm.agents.common.sharding import data_mesh, envs_split_over
    from jaxarm.runner import learners

    overrides = ["env_kwargs.impl=jax", "num_envs=16", "rollout_length=8", "num_minibatches=2"]
    config = apply_overrides(configs.get("ppo_sorter"), overrides)
    with envs_split_over(data_mesh()):
        trainer = learners.make_trainer(config)
        # Lowering embeds every array the program closes over: one on another process's device fails here.
        jax.jit(trainer.init).lower(jax.random.PRNGKey(0), config.hparams())
    print("lowered")
""")


@pytest.mark.slow
@pytest.mark.usefixtures("loaded_cpu")
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
    from experiments import distributed

    def main(argv):
        if argv[argv.index("--process-id") + 1] == "1":
            sys.exit(3)  # as a process that died
        def stopped(signum, frame):
            pathlib.Path(argv[0]).write_text("stopped")
            sys.exit(0)
        signal.signal(signal.SIGTERM, stopped)
        time.sleep(120)

    code = distributed.spawn(main, [sys.argv[1]], 2)
    print("the launcher goes on")  # a Python session that started them is not ended with them
    sys.exit(code)
""")


def test_where_one_local_process_fails_the_launcher_stops_the_others(tmp_path):
    marker = tmp_path / "process0"
    start = time.monotonic()
    launcher = subprocess.run(
        [sys.executable, "-c", ONE_FAILS, str(marker)], capture_output=True, text=True, timeout=120
    )
    assert launcher.returncode == 3, launcher.stderr  # the failed process's code
    assert launcher.stdout.count("the launcher goes on") == 1  # not in the forked processes, which leave at once
    assert marker.read_text() == "stopped"  # process 0 was told to stop (SIGTERM), not left waiting for its peer
    assert time.monotonic() - start < distributed.STOP_GRACE_S


DIES_OR_LOSES_ITS_LAUNCHER = textwrap.dedent("""
    import os, pathlib, signal, sys, time
    from experiments import distributed

    def main(argv):
        marker = pathlib.Path(argv[0]) / argv[argv.index("--process-id") + 1]
        def stopped(signum, frame):
            marker.write_text("stopped" + (" for a failed peer" if distributed.stopped_for_a_failed_peer() else ""))
            sys.exit(0)
        signal.signal(signal.SIGTERM, stopped)
        marker.write_text(str(os.getpid()))
        if sys.argv[2] == "dies" and marker.name == "1":
            os.kill(os.getpid(), signal.SIGKILL)
        time.sleep(120)

    sys.exit(distributed.spawn(main, [sys.argv[1]], 2, "python -m experiments.run --resume RUN"))
""")


def test_a_killed_local_process_is_named_in_one_line_with_the_resume_command(tmp_path):
    launcher = subprocess.run(
        [sys.executable, "-c", DIES_OR_LOSES_ITS_LAUNCHER, str(tmp_path), "dies"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert launcher.returncode == 128 + signal.SIGKILL, launcher.stderr
    assert launcher.stderr == (
        f"error: process 1 (pid {(tmp_path / '1').read_text()}) was killed by SIGKILL; the others are told to stop; "
        "continue with: python -m experiments.run --resume RUN\n"
    )
    assert (tmp_path / "0").read_text() == "stopped for a failed peer"


def test_local_processes_stop_when_their_launcher_is_killed(tmp_path):
    launcher = subprocess.Popen([sys.executable, "-c", DIES_OR_LOSES_ITS_LAUNCHER, str(tmp_path), "orphaned"])
    markers = [tmp_path / "0", tmp_path / "1"]
    start = time.monotonic()
    while not all(marker.exists() and marker.read_text() for marker in markers):
        assert time.monotonic() - start < 60 and launcher.poll() is None
        time.sleep(0.1)
    launcher.kill()
    launcher.wait()
    while not all(marker.read_text() == "stopped" for marker in markers):  # no peer failed: the launcher went
        assert time.monotonic() - start < 60, "a process trains on without its launcher"
        time.sleep(0.1)


SIGTERM_OUTSIDE_THE_LOOP = textwrap.dedent("""
    import pathlib, sys, time
    from experiments import distributed

    def main(argv):
        marker = pathlib.Path(argv[0]) / argv[argv.index("--process-id") + 1]
        marker.write_text("started")
        try:
            time.sleep(120)  # as a process compiling, or evaluating once its chunk loop has ended
        except KeyboardInterrupt:
            marker.write_text("interrupted")
            return 130

    sys.exit(distributed.spawn(main, [sys.argv[1]], 2))
""")


def test_a_local_process_takes_sigterm_outside_its_chunk_loop_as_a_ctrl_c(tmp_path):
    launcher = subprocess.Popen([sys.executable, "-c", SIGTERM_OUTSIDE_THE_LOOP, str(tmp_path)])
    markers = [tmp_path / "0", tmp_path / "1"]
    start = time.monotonic()
    while not all(marker.exists() and marker.read_text() for marker in markers):
        assert time.monotonic() - start < 60 and launcher.poll() is None
        time.sleep(0.1)
    launcher.send_signal(signal.SIGTERM)  # passed on to each: its main ends in its own words, not killed unheard
    assert launcher.wait(timeout=60) == STOPPED_BY_SIGNAL
    assert [marker.read_text() for marker in markers] == ["interrupted", "interrupted"]


def test_a_process_of_no_job_has_no_others_to_wait_for():
    assert not distributed.others_reported(0.1)


def test_a_jax_error_of_a_lost_peer_is_one_line():
    lost = RuntimeError("UNKNOWN: Gloo AllGather failed: [pair.cc:538] Read error: Connection reset by peer\nmore")
    assert distributed.peer_lost_message(lost, 0, "python -m experiments.run --resume RUN") == (
        "error: process 0 stopped: another process of the job has gone (RuntimeError: UNKNOWN: Gloo AllGather "
        "failed: [pair.cc:538] Read error: Connection reset by peer); continue with: python -m experiments.run "
        "--resume RUN"
    )
    assert distributed.peer_lost_message(RuntimeError("out of memory"), 0, "") is None


@pytest.fixture
def stop_signals_restored():
    """SIGINT's and SIGTERM's handlers, put back after a test that leaves a process (which ignores both)."""
    handlers = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    yield
    for signum, handler in handlers.items():
        signal.signal(signum, handler)


@pytest.mark.usefixtures("stop_signals_restored")
def test_a_process_whose_peers_are_gone_leaves_at_once_in_one_line(monkeypatch, capsys):
    lost = RuntimeError("UNKNOWN: Gloo AllGather failed: Connection reset by peer\nmore")
    distributed.leave_if_peers_lost(lost, "RESUME")  # one process alone: its caller says the error
    left = []
    monkeypatch.setattr(distributed, "joined", lambda: True)
    monkeypatch.setattr(distributed, "_leave", left.append)
    distributed.leave_if_peers_lost(RuntimeError("out of memory"), "RESUME")
    assert left == [] and capsys.readouterr().err == ""
    distributed.leave_if_peers_lost(lost, "RESUME")
    assert left == [1]  # at once: JAX's exit hook would wait for the gone peers at its shutdown barrier
    assert capsys.readouterr().err == f"{distributed.peer_lost_message(lost, 0, 'RESUME')}\n"


@pytest.mark.usefixtures("stop_signals_restored")
def test_the_launchers_sigterm_as_a_lost_peer_is_reported_adds_no_second_line(monkeypatch):
    class SignalledAsWritten(io.StringIO):
        def write(self, text: str) -> int:
            os.kill(os.getpid(), signal.SIGTERM)  # the launcher, as it sees the peer's death
            return super().write(text)

    stderr = SignalledAsWritten()
    monkeypatch.setattr(sys, "stderr", stderr)
    monkeypatch.setattr(distributed, "joined", lambda: True)
    monkeypatch.setattr(distributed, "_leave", lambda code: None)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # as in a forked process (`_run_forked`)
    lost = RuntimeError("UNKNOWN: Gloo AllGather failed: Connection reset by peer")
    try:
        distributed.leave_if_peers_lost(lost, "RESUME")
    except KeyboardInterrupt:  # `run.main` reported it in a second line, "interrupted: ..." (2-core CI, 1 run)
        pytest.fail("the SIGTERM came through after the line was said")
    assert stderr.getvalue() == f"{distributed.peer_lost_message(lost, 0, 'RESUME')}\n"


def test_a_failed_shutdown_of_a_finished_process_is_one_line(monkeypatch, capfd):
    def barrier_failed():
        os.write(2, b"E1128 coordination_service.cc:1520] Shutdown barrier in coordination service has failed\n")
        raise RuntimeError("INTERNAL: Shutdown barrier has failed.\nBarrier result: 'DEADLINE_EXCEEDED'")

    monkeypatch.setattr(jax.distributed, "shutdown", barrier_failed)
    distributed.shut_down()
    assert capfd.readouterr().err == (
        "note: JAX could not shut this process down cleanly (INTERNAL: Shutdown barrier has failed.); what it wrote "
        "is kept\n"
    )


@pytest.mark.slow
@pytest.mark.usefixtures("loaded_cpu")
@pytest.mark.parametrize("victim", ["process 0", "process 1", "launcher"])
def test_a_run_of_two_local_processes_ends_in_one_line_when_one_or_its_launcher_is_killed(tmp_path, victim):
    run_dir = tmp_path / "run"
    launcher = subprocess.Popen(
        [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d", "--local-processes", "2"]
        + ["--out", str(run_dir), *OVERRIDES[:-5], "total_env_steps=1000000", *OVERRIDES[-4:]],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for_chunks(run_dir, 2, launcher)
    children = [
        int(pid) for pid in pathlib.Path(f"/proc/{launcher.pid}/task/{launcher.pid}/children").read_text().split()
    ]
    pid = {"process 0": children[0], "process 1": children[1], "launcher": launcher.pid}[victim]
    os.kill(pid, signal.SIGKILL)
    _, err = launcher.communicate(timeout=120)  # the pipes close once every process has gone
    assert not any(alive(child) for child in children), "a process of the run was left behind"
    lines = [line for line in err.splitlines() if line.startswith(("error:", "interrupted:", "Traceback"))]
    resume = f"continue with: python -m experiments.run --resume {run_dir}"
    if victim != "launcher":
        assert launcher.returncode == 128 + signal.SIGKILL
        killed = f"error: process {victim[-1]} (pid {pid}) was killed by SIGKILL; the others are told to stop; {resume}"
        # The launcher's line ends the output: the survivor that lost process 0, and with it JAX's coordination
        # service, may end in JAX's abort first, a block of C++ logs (its hook for that is unusable from Python).
        assert err.strip().splitlines()[-1] == killed and "Traceback" not in err, err
        # The survivor's own line, where its collective failed before the launcher's SIGTERM ended it (the two race).
        gone = ("Gloo", "another process of the job has gone")
        assert all(any(word in line for word in gone) for line in lines if line != killed), err
        assert len(lines) <= 2, err
    else:  # each process checkpoints and says so
        assert len(lines) == 2 and all(line.startswith("interrupted: checkpoint at update ") for line in lines), err
        assert all(line.endswith(resume) for line in lines)


def wait_for_chunks(run_dir: pathlib.Path, count: int, running: subprocess.Popen) -> None:
    """Returns once the run in `run_dir` has logged `count` chunks of OVERRIDES (2 updates each), `running` alive."""
    metrics, start = run_dir / "metrics.jsonl", time.monotonic()
    while not (metrics.exists() and metrics.read_text().count("\n") >= 2 * count):
        assert running.poll() is None and time.monotonic() - start < 300, running.communicate()[1][-3000:]
        time.sleep(0.2)


@pytest.mark.slow
@pytest.mark.usefixtures("loaded_cpu")
def test_a_distributed_process_whose_peer_is_killed_ends_in_one_line(tmp_path):
    run_dir = tmp_path / "run"
    long_run = [*OVERRIDES[:-5], "total_env_steps=1000000", *OVERRIDES[-4:]]
    first, second = start_processes(2, ["--config", "ppo_arm2d", "--out", str(run_dir), *long_run])
    wait_for_chunks(run_dir, 2, first)
    second.kill()
    second.communicate()
    _, err = first.communicate(timeout=120)  # its next collective finds its peer gone
    assert first.returncode == 1 and "Traceback" not in err, err[-3000:]
    assert err.strip().splitlines()[-1].startswith("error: process 0 stopped: another process of the job has gone")
    assert err.strip().endswith(f"; continue with: python -m experiments.run --resume {run_dir}")


def test_local_processes_are_forked_only_before_jax_starts_its_backend():
    jax.devices()
    with pytest.raises(RuntimeError, match="before JAX starts its backend"):
        distributed.spawn(run.main, ["--config", "ppo_arm2d"], 2)


def test_a_local_process_writes_each_line_whole_though_python_writes_through():
    # PYTHONUNBUFFERED=1 (write-through): two processes' errors came out as one line on a loaded CPU, then two ends.
    writes = []

    class Recorder(io.RawIOBase):
        def writable(self):
            return True

        def write(self, data):
            writes.append(bytes(data))
            return len(data)

    stream = io.TextIOWrapper(Recorder(), write_through=True)  # as Python makes stderr where it writes through
    print("error: a", file=stream)
    distributed.one_write_per_line(stream)
    print("error: b", file=stream)
    assert writes == [b"error: a", b"\n", b"error: b\n"]


@pytest.mark.parametrize(("code", "status"), [(None, 0), (0, 0), (3, 3), ("a message", 1)])
def test_a_forked_process_exits_as_sys_exit_would(code, status):
    assert distributed.exit_code(code) == status


def test_the_joining_options_are_checked_before_jax_reads_them(capsys):
    parser = argparse.ArgumentParser(prog="run")
    distributed.add_arguments(parser, "--out")
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        taken = listening.getsockname()[1]
        for argv, message in [
            (["--coordinator", "node7"], "argument --coordinator: 'node7' is not HOST:PORT"),
            (["--coordinator", "node7:http"], "argument --coordinator: 'node7:http': its port 'http' is not a number"),
            (["--coordinator", "node7:70000"], "its port '70000' is not a number from 1 to 65535"),
            (["--coordinator", ":1234"], "':1234' is not HOST:PORT"),
            (["--num-processes", "0"], "--num-processes takes a count of 1 or more, got 0"),
            (["--num-processes", "2", "--process-id", "2"], "--process-id 2 is not below --num-processes 2"),
            (["--process-id", "-1"], "--process-id takes 0 or more, got -1"),
            (["--join-timeout", "0"], "--join-timeout takes seconds in (0, 86400], got 0.0"),
            (["--join-timeout", "nan"], "--join-timeout takes seconds in (0, 86400], got nan"),
            (["--coordinator", f"localhost:{taken}", "--process-id", "0"], f"port {taken} is in use on this host"),
        ]:
            with pytest.raises(SystemExit) as exited:
                distributed.check_arguments(parser, parser.parse_args(["--distributed", *argv]))
            assert exited.value.code == 2
            error = capsys.readouterr().err
            assert error.startswith("usage: run") and error.splitlines()[-1].startswith("run: error: ")
            assert message in error.splitlines()[-1]
        # The other processes only connect to the coordinator's port.
        distributed.check_arguments(
            parser, parser.parse_args(["--distributed", "--coordinator", f"localhost:{taken}", "--process-id", "1"])
        )


HELD_AT_A_CHECKPOINT = textwrap.dedent("""
    import os, pathlib, sys, time
    import orbax.checkpoint as ocp
    from experiments import run

    marks = pathlib.Path(sys.argv[1])
    finalize = ocp.StandardCheckpointHandler.finalize
    calls = []

    def held(handler, directory):
        # Process 0 commits each checkpoint that both wrote, process 1 waiting for it in orbax's barrier: the
        # second is held there, whole in its temporary folder but not committed, until the test releases it.
        calls.append(directory)
        if len(calls) == 2:
            (marks / "held").write_text(str(os.getpid()))
            while not (marks / "released").exists():
                time.sleep(0.05)
        finalize(handler, directory)

    ocp.StandardCheckpointHandler.finalize = held
    sys.exit(run.main(sys.argv[2:]))
""")
CHECKPOINTED = [*OVERRIDES, "checkpoint_every_updates=2"]
"""OVERRIDES with a checkpoint at every chunk end: at updates 2, 4, 6 and 8."""


@pytest.fixture(scope="module")
def two_processes_uninterrupted(tmp_path_factory) -> pathlib.Path:
    """A run of CHECKPOINTED by two local processes, from start to end."""
    run_dir = tmp_path_factory.mktemp("uninterrupted") / "run"
    args = ["--config", "ppo_arm2d", "--local-processes", "2", "--out", str(run_dir), *CHECKPOINTED]
    assert_codes(run_processes(1, args), 0)
    return run_dir


def alive(pid: int) -> bool:
    """Whether process `pid` runs (not ended, nor a zombie waiting for its parent)."""
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.slow
@pytest.mark.usefixtures("loaded_cpu")
@pytest.mark.parametrize("victim", ["process 0", "process 1", "launcher"])
def test_a_kill_while_two_processes_write_a_checkpoint_is_one_line_and_resumes_bit_identically(
    tmp_path, victim, two_processes_uninterrupted
):
    run_dir = tmp_path / "run"
    launcher = subprocess.Popen(
        [sys.executable, "-c", HELD_AT_A_CHECKPOINT, str(tmp_path), "--config", "ppo_arm2d"]
        + ["--local-processes", "2", "--out", str(run_dir), *CHECKPOINTED],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    start = time.monotonic()
    while not (tmp_path / "held").exists():
        assert launcher.poll() is None and time.monotonic() - start < 300, launcher.communicate()[1][-3000:]
        time.sleep(0.1)
    assert checkpoint.half_written(run_dir / "checkpoints"), "checkpoint 4 is being written"
    children = [
        int(pid) for pid in pathlib.Path(f"/proc/{launcher.pid}/task/{launcher.pid}/children").read_text().split()
    ]
    pid = {"process 0": children[0], "process 1": children[1], "launcher": launcher.pid}[victim]
    os.kill(pid, signal.SIGKILL)
    (tmp_path / "released").write_text("")
    _, err = launcher.communicate(timeout=180)  # the pipes close once every process has gone
    assert not any(alive(child) for child in children), "a process of the run was left behind"
    if victim == "process 0":
        # Process 1 loses JAX's coordination service with it, and JAX aborts it after its own block of C++ logs.
        assert "Traceback" not in err, err[-3000:]
    else:
        assert_quiet(subprocess.CompletedProcess(launcher.args, launcher.returncode, "", err))
    lines = [line for line in err.splitlines() if line.startswith(("error:", "interrupted:"))]
    resume = f"continue with: python -m experiments.run --resume {run_dir}"
    if victim == "launcher":  # each process checkpoints and says so
        assert len(lines) == 2 and all(line.startswith("interrupted: checkpoint at update ") for line in lines), err
        assert all(line.endswith(resume) for line in lines)
    else:
        assert launcher.returncode == 128 + signal.SIGKILL
        index = victim.split()[1]
        killed = f"error: process {index} (pid {pid}) was killed by SIGKILL; the others are told to stop; {resume}"
        assert err.strip().splitlines()[-1] == killed and len(lines) <= 2, err
        # The survivor's own line, where its checkpoint met the loss before the launcher's SIGTERM ended it.
        assert all("another process of the job has gone" in line for line in lines if line != killed), err
    assert_codes(run_processes(1, ["--resume", str(run_dir), "--local-processes", "2"]), 0)
    assert [row["updates"] for row in read_metrics(run_dir)] == list(range(1, 9))
    assert_same_learner(run_dir, two_processes_uninterrupted)
