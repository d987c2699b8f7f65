"""The seeds protocol: separate runs per seed, the worst seed, the interval, resume; runs that reproduce."""

import argparse
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from experiments import seeds
from jaxarm.runner import metrics_log, rundir, stats
from tests.experiments.test_run import SMALL  # the same compiled chunk as there


@pytest.mark.parametrize(
    ("text", "expected"), [("0-4", (0, 1, 2, 3, 4)), ("7", (7,)), ("0,3,7", (0, 3, 7)), ("0-1,10", (0, 1, 10))]
)
def test_seeds_are_read_as_ranges_and_lists(text, expected):
    assert seeds.parse_seeds(text) == expected


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("a", "expected seeds"),
        ("0-1,1", "twice"),
        ("0-5000", "at most"),
        ("0-2,5-3", "seeds 5-3 run backwards; give 3-5"),
        ("0--1", "each 0 or more"),
        ("0-99999999999999", "at most 1000 seeds"),  # refused before a range of that length is made
    ],
)
def test_bad_seeds_are_refused_in_one_line(text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        seeds.parse_seeds(text)


@pytest.mark.parametrize("text", ["0", "-1", "nan", "inf", "soon"])
def test_a_time_limit_no_command_can_meet_is_refused_in_one_line(text):
    with pytest.raises(argparse.ArgumentTypeError, match="minutes"):
        seeds.time_limit(text)
    assert seeds.time_limit("0.5") == 0.5


def test_the_interval_holds_the_mean_reads_the_same_twice_and_is_a_point_where_all_agree():
    values = np.array([0.659, 0.73, 1.0, 1.0, 1.0])
    low, high = stats.bootstrap_interval(values)
    assert low < values.mean() < high
    assert (low, high) == stats.bootstrap_interval(values)
    assert low >= values.min() and high <= values.max()
    assert stats.bootstrap_interval(np.array([1.0, 1.0, 1.0])) == (1.0, 1.0)


def result(seed: int, placed: float, wall_s: float = 60.0, finished: bool = True) -> seeds.SeedResult:
    return seeds.SeedResult(seed=seed, placed=placed, wall_s=wall_s, finished=finished, device="cpu")


def test_a_study_is_met_only_when_its_worst_seed_meets_the_goal_in_time():
    protocol = seeds.Protocol("ppo_arm2d", (0, 1, 2), goal=0.95, minutes=2.0, overrides=())
    met = seeds.summarise(protocol, [result(0, 0.99), result(1, 0.96), result(2, 1.0)])
    assert met["met"] and met["worst"] == 0.96 and met["devices"] == ["cpu"]
    assert not seeds.summarise(protocol, [result(0, 0.99), result(1, 0.94), result(2, 1.0)])["met"]
    assert not seeds.summarise(protocol, [result(0, 0.99), result(1, 0.99, wall_s=121), result(2, 1.0)])["met"]
    stopped = seeds.summarise(protocol, [result(0, 0.99), result(1, 0.99, finished=False), result(2, 1.0)])
    assert not stopped["met"] and stopped["worst"] is None
    assert "**met**" in seeds.markdown(met) and "(not finished)" in seeds.markdown(stopped)


def write_robustness(
    run_dir: pathlib.Path, request: list[str], update: int, rows: list[tuple[str, float | None, float]]
):
    """A robustness table as `experiments.eval` writes it of `update`'s checkpoint: rows (param, value, placed)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "eval.json").write_text(json.dumps({"success_rate": 0.99, "finished": True, "device": "cpu"}))
    table = [{"param": param, "value": value, "success_rate": placed} for param, value, placed in rows]
    stem = rundir.robustness_stem(run_dir, 16, 12345, str(update), request)
    recorded = {"device": "cpu", "perturb": request, "episodes": 16, "checkpoint": str(update), "rows": table}
    stem.with_suffix(".json").write_text(json.dumps(recorded))


def test_each_finished_seed_is_evaluated_once_and_the_study_tabulates_the_worst_seed_per_perturbation(tmp_path):
    protocol = seeds.Protocol(
        "ppo_arm2d", (0, 1, 2), 0.9, None, (), perturb=("action_scale=0.2",), worst_corner=True, perturb_episodes=16
    )
    request = ["action_scale=0.2", "--worst-corner"]
    assert protocol.robustness_request == request
    assert protocol.command == (
        "python -m experiments.seeds --config ppo_arm2d --seeds 0,1,2 --goal 0.9 --perturb-episodes 16 --worst-corner "
        "--perturb action_scale=0.2"
    )
    write_robustness(seeds.seed_dir(tmp_path, 0), request, 30, [("nominal", None, 0.5)])  # an older checkpoint's
    write_robustness(
        seeds.seed_dir(tmp_path, 0),
        request,
        300,
        [("nominal", None, 1.0), ("action_scale", 0.2, 0.75), ("worst corner: goal_size=20", None, 0.5)],
    )
    write_robustness(seeds.seed_dir(tmp_path, 1), ["action_scale=0.2"], 300, [("nominal", None, 1.0)])  # not asked
    (seeds.seed_dir(tmp_path, 2)).mkdir()  # not finished
    assert seeds.evaluation_command(protocol, tmp_path, 0) is None  # written
    assert seeds.evaluation_command(protocol, tmp_path, 1) == [
        "python", "-m", "experiments.eval", str(seeds.seed_dir(tmp_path, 1)), "--episodes", "16",
        "--perturb", "action_scale=0.2", "--worst-corner",
    ]  # fmt: skip
    assert seeds.evaluation_command(protocol, tmp_path, 2) is None  # its training first
    assert [command.seed for command in seeds.pending_commands(protocol, tmp_path, None)] == [2, 1]

    results = [result(0, 0.99), result(1, 0.97), result(2, 0.98)]
    summary = seeds.summarise(protocol, results, seeds.robustness_tables(protocol, tmp_path))
    nominal, scaled, corner = summary["robustness"]
    assert nominal["placed"] == {"0": 1.0, "1": None, "2": None} and nominal["worst"] is None
    assert scaled["perturbation"] == "action_scale=0.2" and scaled["placed"]["0"] == 0.75
    assert corner["perturbation"] == "worst corner" and summary["worst_corners"] == {"0": "goal_size=20"}
    text = seeds.markdown(summary)
    assert "| action_scale=0.2 | 75.0% | — | — | — | — |" in text and "- seed 0: goal_size=20" in text

    for seed in (1, 2):
        write_robustness(
            seeds.seed_dir(tmp_path, seed),
            request,
            300,
            [("nominal", None, 1.0), ("action_scale", 0.2, 0.25 * seed), ("worst corner: goal_size=60", None, 1.0)],
        )
    summary = seeds.summarise(protocol, results, seeds.robustness_tables(protocol, tmp_path))
    scaled = summary["robustness"][1]
    assert scaled["worst"] == 0.25 and scaled["mean"] == pytest.approx(0.5) and len(scaled["interval"]) == 2
    assert "| action_scale=0.2 | 75.0% | 25.0% | 50.0% | 25.0% | 50.0% |" in seeds.markdown(summary)
    assert seeds.pending_commands(protocol, tmp_path, None) == []


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--perturb", "no_such_param=1"], "--perturb: "),
        (["--perturb", "action_scale=-1"], "--perturb: "),
        (["--perturb", "action_scale"], "--perturb: a perturbation is NAME=V1,V2,..., got 'action_scale'"),
        (["--perturb", "action_scale=0.2", "num_envs=8"], "(config overrides go before --perturb)"),
        (["--worst-corner"], "--worst-corner: ppo_arm2d randomises no env param"),
    ],
)
def test_a_perturbation_the_eval_would_refuse_is_one_line_before_any_run_starts(tmp_path, capsys, extra, message):
    out = tmp_path / "study"
    assert seeds.main(["--config", "ppo_arm2d", "--seeds", "0", "--out", str(out), *extra]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("error: ") and message in line
    assert not out.exists()


def test_perturb_episodes_without_a_perturbation_is_refused(capsys):
    with pytest.raises(SystemExit) as exited:
        seeds.parse_args(["--config", "ppo_arm2d", "--perturb-episodes", "8"])
    assert exited.value.code == 2 and "give one of them" in capsys.readouterr().err
    with pytest.raises(ValueError, match="perturb_episodes"):
        seeds.Protocol("ppo_arm2d", (0,), 0.9, None, (), perturb=("action_scale=0.2",), perturb_episodes=0)


def test_a_seed_reports_the_tries_its_run_took(tmp_path):
    seeds.seed_dir(tmp_path, 3).mkdir()
    evaluation = {"success_rate": 0.9, "finished": True, "device": "cpu"}
    (seeds.seed_dir(tmp_path, 3) / "eval.json").write_text(json.dumps(evaluation))
    assert seeds.seed_result(tmp_path, 3, [5.0]).tries == 1  # a run without a gate wrote none
    (seeds.seed_dir(tmp_path, 3) / "eval.json").write_text(json.dumps({**evaluation, "tries": 3}))
    assert seeds.seed_result(tmp_path, 3, [5.0]) == seeds.SeedResult(3, 0.9, 5.0, True, "cpu", tries=3)
    protocol = seeds.Protocol("ppo_arm2d", (3,), goal=0.8, minutes=None, overrides=())
    table = seeds.markdown(seeds.summarise(protocol, [seeds.seed_result(tmp_path, 3, [5.0])]))
    assert "| seed | placed | command wall | tries | device |" in table and "| 3 | 90.0% | 5 s | 3 | cpu |" in table


def test_studies_side_by_side_take_each_gpu_for_one_run_at_a_time(tmp_path):
    gpu0, gpu1 = seeds.Slot("0"), seeds.Slot("1")
    first, second = seeds.GpuPool([gpu0, gpu1], tmp_path), seeds.GpuPool([gpu0, gpu1], tmp_path)
    assert first.take() == gpu0
    assert second.take() == gpu1  # GPU 0 is the first study's
    assert first.take() is second.take() is None
    first.give_back(gpu0)
    assert second.take() == gpu0
    assert first.take() is None


def test_runs_per_gpu_spread_over_the_gpus_first_and_share_each_up_to_the_largest_study_s_count(tmp_path, monkeypatch):
    monkeypatch.setattr(seeds.distributed, "gpus_here", lambda: 2)
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "3,5")
    slots = seeds.gpu_slots(2)
    assert [(slot.gpu, slot.share) for slot in slots] == [("3", 0), ("5", 0), ("3", 1), ("5", 1)]
    sharing, alone = seeds.GpuPool(slots, tmp_path), seeds.GpuPool(seeds.gpu_slots(1), tmp_path)
    assert sharing.take() == slots[0]
    assert alone.take() == slots[1]  # GPU 5's first share
    # GPU 5's second share: it holds two runs, the largest count of the two studies, and no more.
    assert [sharing.take(), sharing.take()] == slots[2:]
    assert sharing.take() is None and alone.take() is None


def test_a_host_without_gpus_runs_one_run_at_a_time_per_study_and_locks_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(seeds.distributed, "gpus_here", lambda: 0)
    cpu = seeds.gpu_slots(1)
    assert cpu == [seeds.Slot(None)] and seeds.gpu_slots(3) == [seeds.Slot(None, share) for share in range(3)]
    first, second = seeds.GpuPool(cpu, tmp_path / "locks"), seeds.GpuPool(cpu, tmp_path / "locks")
    assert first.take() == second.take() == cpu[0]
    assert first.take() is None
    first.give_back(cpu[0])
    assert first.take() == cpu[0]
    assert not (tmp_path / "locks").exists()


def test_a_seed_the_config_refuses_is_one_line_before_any_run_starts(tmp_path, capsys):
    out = tmp_path / "study"
    assert seeds.main(["--config", "ppo_arm2d", "--seeds", "0,2147483648", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == "error: seed must fit in int32 (at most 2,147,483,647 in magnitude), got 2,147,483,648\n"
    assert not out.exists()


@pytest.mark.parametrize("content", ["null", "{", "[1]"])  # tracebacks from the study before
def test_a_seed_whose_eval_json_is_damaged_counts_as_not_finished(tmp_path, content):
    seeds.seed_dir(tmp_path, 3).mkdir()
    (seeds.seed_dir(tmp_path, 3) / "eval.json").write_text(content)
    assert seeds.seed_result(tmp_path, 3, [5.0]) == seeds.SeedResult(3, None, 5.0, False, None)
    assert seeds.next_command(seeds.Protocol("ppo_arm2d", (3,), 0.9, None, ()), tmp_path, 3, None) is not None


def test_a_study_whose_run_failed_says_so_in_one_line_and_fails(tmp_path, capsys):
    out = tmp_path / "study"
    (out / "seed-0").mkdir(parents=True)
    (out / "seed-0" / "notes.txt").write_text("mine")  # the run refuses a directory of foreign files (rc 2)
    assert seeds.main(["--config", "ppo_arm2d", "--seeds", "0", "--out", str(out), *SMALL]) == 2  # 0 before
    (line,) = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert line == (
        f"error: the runs of seeds 0 failed (their logs say why: {seeds.seed_log(out, 0)}); fix that and continue "
        f"with: python -m experiments.seeds --resume {out}"
    )
    assert "holds files but no run" in seeds.seed_log(out, 0).read_text()


def test_a_resumed_study_takes_no_out_overrides_runs_per_gpu_or_perturbations(tmp_path, capsys):
    # Each was left aside without a word: the study keeps what its seeds.json says.
    asked = (
        ["--out", str(tmp_path / "elsewhere")],
        ["num_envs=8"],
        ["--runs-per-gpu", "2"],
        ["--perturb", "action_scale=0.2"],
        ["--worst-corner"],
        ["--perturb-episodes", "8"],
    )
    for extra in asked:
        with pytest.raises(SystemExit) as exited:
            seeds.parse_args(["--resume", str(tmp_path), *extra])
        err = capsys.readouterr().err
        assert exited.value.code == 2 and "give no overrides, --out, --runs-per-gpu, --perturb, --worst-corner" in err


@pytest.mark.parametrize("text", ["0", "17", "two"])
def test_runs_per_gpu_out_of_range_is_refused_in_one_line(text, capsys):
    with pytest.raises(SystemExit) as exited:
        seeds.parse_args(["--config", "ppo_arm2d", "--runs-per-gpu", text])
    assert exited.value.code == 2
    assert f"expected an integer from 1 to 16, got '{text}'" in capsys.readouterr().err


def test_a_damaged_study_file_is_named_in_one_line(tmp_path):
    (tmp_path / seeds.SEEDS_FILE).write_text(json.dumps({"config": "ppo_arm2d"}))
    with pytest.raises(ValueError, match=f"{seeds.SEEDS_FILE} is damaged"):
        seeds.read_study(tmp_path)
    with pytest.raises(ValueError, match="holds no"):
        seeds.read_study(tmp_path / "nothing")
    study = {"config": "ppo_arm2d", "seeds": [0], "goal": 0.9, "minutes": None, "overrides": [], "walls": {}}
    (tmp_path / seeds.SEEDS_FILE).write_text(json.dumps({**study, "runs_per_gpu": 0}))  # no slot: it waited forever
    with pytest.raises(ValueError, match=f"{seeds.SEEDS_FILE} is damaged .*runs_per_gpu must be from 1 to 16, got 0"):
        seeds.read_study(tmp_path)
    (tmp_path / seeds.SEEDS_FILE).write_text(json.dumps(study))  # a study from before the option: one run per GPU
    assert seeds.read_study(tmp_path)[0].runs_per_gpu == 1


def test_a_command_a_killed_study_never_saw_end_counts_to_its_logs_last_line(tmp_path, capsys):
    # A study killed outright by a machine's time limit kept no wall clock of the command it was running: its
    # seed's table showed the resumed command's 345 s alone, where the seed had taken ~945 s.
    started = time.time() - 1000.0
    study = {"config": "ppo_arm2d", "seeds": [0, 1], "goal": 0.9, "minutes": 30.0, "overrides": []}
    saved = {**study, "walls": {"0": [50.0]}, "unended": {"0": started, "1": started}}
    (tmp_path / seeds.SEEDS_FILE).write_text(json.dumps(saved))
    seeds.seed_log(tmp_path, 0).write_text("interrupted: checkpoint at update 340 saved\n")
    os.utime(seeds.seed_log(tmp_path, 0), (started + 600.0, started + 600.0))
    _, _, walls = seeds.open_study(seeds.parse_args(["--resume", str(tmp_path)]))
    assert walls == {0: [50.0, pytest.approx(600.0)]}  # seed 1's command wrote no log: it never started
    assert "seed 0: its last command was not seen to end" in capsys.readouterr().err


@pytest.mark.parametrize("stage", ["", rundir.TEACHER_DIR, rundir.WARM_START_DIR])
def test_a_seed_stopped_in_any_stage_resumes_and_one_without_checkpoints_starts_again(tmp_path, stage):
    protocol = seeds.Protocol("ppo_sorter3", (4,), 0.8, 15.0, ())
    run_dir = seeds.seed_dir(tmp_path, 4)
    (run_dir / stage / "checkpoints").mkdir(parents=True)
    (run_dir / "config.json").write_text("{}")
    assert seeds.next_command(protocol, tmp_path, 4, 9.0) == protocol.run_command(4, run_dir) + [
        "--stop-after-minutes",
        "9",
    ]
    (run_dir / stage / "checkpoints" / "80").mkdir()
    resume = ["python", "-m", "experiments.run", "--resume", str(run_dir), "--stop-after-minutes", "9"]
    assert seeds.next_command(protocol, tmp_path, 4, 9.0) == resume


def computed(run_dir: pathlib.Path) -> tuple[list[dict], dict]:
    """A run's metrics rows and final evaluation less their clocks: what it computed."""
    rows = [
        {k: v for k, v in row.items() if k not in {"wall_time", "steps_per_second"}}
        for row in metrics_log.read_metrics(run_dir)
    ]
    evaluation = json.loads((run_dir / "eval.json").read_text())
    return rows, {k: v for k, v in evaluation.items() if k != "train_wall_time"}


@pytest.mark.slow
def test_each_seed_is_a_separate_run_a_stopped_one_resumes_and_reproduces_an_unstopped_one(tmp_path, capsys):
    """Seed 0 runs to its end; the study's seeds 0 and 1, run two at a time, stop after their first chunk and
    resume. Seed 0's two runs, separate processes of the same command and seed, write the same metrics row for row
    and the same evaluation: a result is reproducible where XLA computes it alike (the CPU), alone or beside
    another run."""
    args = ["--config", "ppo_arm2d_fixed", "--goal", "0.0", *SMALL]
    assert seeds.main([*args, "--seeds", "0", "--out", str(tmp_path / "whole")]) == 0
    stopped = tmp_path / "stopped"
    two = ["--runs-per-gpu", "2", "--stop-after-minutes", "0"]
    assert seeds.main([*args, "--seeds", "0-1", "--out", str(stopped), *two]) == 0
    assert "continue them with: python -m experiments.seeds --resume" in capsys.readouterr().out
    assert seeds.main(["--resume", str(stopped)]) == 0
    summary = json.loads((stopped / "summary.json").read_text())
    assert summary["met"] and summary["finished"] and [seed["seed"] for seed in summary["seeds"]] == [0, 1]
    assert summary["runs_per_gpu"] == 2 and "--runs-per-gpu 2" in summary["command"]  # kept by --resume
    assert "2 runs shared each GPU at a time" in (stopped / "seeds.md").read_text()
    walls = json.loads((stopped / seeds.SEEDS_FILE).read_text())["walls"]
    assert [len(walls[seed]) for seed in ("0", "1")] == [2, 2]
    assert seeds.main(["--resume", str(stopped)]) == 0  # nothing left to run
    assert json.loads((stopped / seeds.SEEDS_FILE).read_text())["walls"] == walls
    assert "seed-0:" not in capsys.readouterr().out
    assert computed(tmp_path / "whole" / "seed-0") == computed(stopped / "seed-0")


@pytest.mark.slow
def test_a_study_evaluates_each_seed_under_its_perturbations_as_experiments_eval_does(tmp_path, capsys):
    out = tmp_path / "study"
    perturb = ["--perturb-episodes", "16", "--perturb", "action_scale=0.05,0.2"]
    assert (
        seeds.main(["--config", "ppo_arm2d_fixed", "--seeds", "0", "--goal", "0", "--out", str(out), *SMALL, *perturb])
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    rows = summary["robustness"]
    assert [row["perturbation"] for row in rows] == ["nominal", "action_scale=0.05", "action_scale=0.2"]
    (table,) = seeds.seed_dir(out, 0).glob("robustness-16-*.json")  # the eval's own, as a user's command writes it
    written = {(row["param"], row["value"]): row["success_rate"] for row in json.loads(table.read_text())["rows"]}
    assert [row["worst"] for row in rows] == [
        written[("nominal", None)],
        written[("action_scale", 0.05)],
        written[("action_scale", 0.2)],
    ]
    assert summary["command"].endswith("--perturb-episodes 16 --perturb action_scale=0.05,0.2")
    assert "seed 0: robustness evaluation rc 0" in capsys.readouterr().out
    assert seeds.main(["--resume", str(out)]) == 0  # nothing left to run
    assert "robustness evaluation" not in capsys.readouterr().out


@pytest.mark.slow
def test_sigterm_stops_the_study_and_its_runs_at_a_checkpoint_leaving_none_running(tmp_path):
    out = tmp_path / "study"
    command = [sys.executable, "-m", "experiments.seeds", "--config", "ppo_arm2d_fixed", "--seeds", "0", "--goal", "0"]
    long = [*SMALL, "total_env_steps=24576000"]  # far more than the test waits for
    process = subprocess.Popen([*command, "--out", str(out), *long], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while not rundir.any_checkpoint_files(out / "seed-0") and time.monotonic() < deadline:
        time.sleep(0.5)
    run_pid = int((out / "seed-0" / ".lock").read_text())
    assert list(json.loads((out / seeds.SEEDS_FILE).read_text())["unended"]) == ["0"]  # for a killed study's resume
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == 130, stderr[-2000:]
    assert stderr.strip().splitlines()[-1] == f"interrupted; continue with: python -m experiments.seeds --resume {out}"
    with pytest.raises(ProcessLookupError):
        os.kill(run_pid, 0)
    saved = json.loads((out / seeds.SEEDS_FILE).read_text())
    assert len(saved["walls"]["0"]) == 1 and saved["unended"] == {}


SORTER_TINY = [
    "env_kwargs.impl=jax",
    "num_envs=8",
    "rollout_length=8",
    "num_minibatches=2",
    "num_epochs=1",
    "total_env_steps=128",
    "updates_per_chunk=1",
    "checkpoint_every_updates=2",
    "shuffle_groups=1",
    "eval_episodes=8",
    "eval_env_params.max_episode_steps=20",
]


@pytest.mark.slow
@pytest.mark.mjx
def test_two_runs_of_one_command_and_seed_on_mjx_jax_compute_the_same(tmp_path):
    """The same command and seed, run twice as a user runs it (two processes, the second reading the first's
    compiled programs from the cache), give the same metrics row for row and the same evaluation on MJX-JAX."""
    for name in ("first", "second"):
        command = [sys.executable, "-m", "experiments.run", "--config", "ppo_sorter", "--out", str(tmp_path / name)]
        done = subprocess.run([*command, *SORTER_TINY, "seed=3"], capture_output=True, text=True, timeout=1200)
        assert done.returncode == 0, done.stderr[-2000:]
    assert computed(tmp_path / "first") == computed(tmp_path / "second")
