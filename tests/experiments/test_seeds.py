"""The seeds protocol: separate runs per seed, the worst seed, the interval, resume; runs that reproduce."""

import argparse
import json
import pathlib

import numpy as np
import pytest

from experiments import seeds
from jaxarm.runner import rundir

SMALL = [
    "num_envs=64",
    "rollout_length=16",
    "num_minibatches=2",
    "total_env_steps=24576",
    "updates_per_chunk=4",
    "checkpoint_every_updates=4",
    "eval_episodes=20",
]


@pytest.mark.parametrize(
    ("text", "expected"), [("0-4", (0, 1, 2, 3, 4)), ("7", (7,)), ("0,3,7", (0, 3, 7)), ("0-1,10", (0, 1, 10))]
)
def test_seeds_are_read_as_ranges_and_lists(text, expected):
    assert seeds.parse_seeds(text) == expected


@pytest.mark.parametrize(("text", "message"), [("a", "expected seeds"), ("0-1,1", "twice"), ("0-5000", "at most")])
def test_bad_seeds_are_refused_in_one_line(text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        seeds.parse_seeds(text)


def test_the_interval_holds_the_mean_reads_the_same_twice_and_is_a_point_where_all_agree():
    values = np.array([0.659, 0.73, 1.0, 1.0, 1.0])
    low, high = seeds.bootstrap_interval(values)
    assert low < values.mean() < high
    assert (low, high) == seeds.bootstrap_interval(values)
    assert low >= values.min() and high <= values.max()
    assert seeds.bootstrap_interval(np.array([1.0, 1.0, 1.0])) == (1.0, 1.0)


def result(seed: int, placed: float, wall_s: float = 60.0, finished: bool = True) -> seeds.SeedResult:
    return seeds.SeedResult(seed=seed, placed=placed, wall_s=wall_s, finished=finished, device="cpu")


def test_a_study_is_met_only_when_its_worst_seed_meets_the_goal_in_time():
    protocol = seeds.Protocol("ppo_arm2d", (0, 1, 2), goal=0.95, minutes=2.0, overrides=())
    met = seeds.summarise(protocol, [result(0, 0.99), result(1, 0.96), result(2, 1.0)], "cmd")
    assert met["met"] and met["worst"] == 0.96 and met["devices"] == ["cpu"]
    assert not seeds.summarise(protocol, [result(0, 0.99), result(1, 0.94), result(2, 1.0)], "cmd")["met"]
    assert not seeds.summarise(protocol, [result(0, 0.99), result(1, 0.99, wall_s=121), result(2, 1.0)], "cmd")["met"]
    stopped = seeds.summarise(protocol, [result(0, 0.99), result(1, 0.99, finished=False), result(2, 1.0)], "cmd")
    assert not stopped["met"] and stopped["worst"] is None
    assert "**met**" in seeds.markdown(met) and "(stopped)" in seeds.markdown(stopped)


def test_a_damaged_study_file_is_named_in_one_line(tmp_path):
    (tmp_path / seeds.SEEDS_FILE).write_text(json.dumps({"config": "ppo_arm2d"}))
    with pytest.raises(ValueError, match=f"{seeds.SEEDS_FILE} is damaged"):
        seeds.read_study(tmp_path)
    with pytest.raises(ValueError, match="holds no"):
        seeds.read_study(tmp_path / "nothing")


@pytest.mark.slow
def test_each_seed_is_a_separate_run_a_stopped_one_resumes_and_reproduces_an_unstopped_one(tmp_path, capsys):
    """Seed 0 runs to its end; the study's seeds 0 and 1 stop after their first chunk and resume. Seed 0's two runs,
    separate processes of the same command and seed, write the same metrics row for row and the same evaluation:
    a result is reproducible where XLA computes it alike (the CPU)."""
    args = ["--config", "ppo_arm2d_fixed", "--goal", "0.0", *SMALL]
    assert seeds.main([*args, "--seeds", "0", "--out", str(tmp_path / "whole")]) == 0
    stopped = tmp_path / "stopped"
    assert seeds.main([*args, "--seeds", "0-1", "--out", str(stopped), "--stop-after-minutes", "0"]) == 0
    assert "continue with: python -m experiments.seeds --resume" in capsys.readouterr().out
    assert seeds.main(["--resume", str(stopped)]) == 0
    summary = json.loads((stopped / "summary.json").read_text())
    assert summary["met"] and summary["finished"] and [seed["seed"] for seed in summary["seeds"]] == [0, 1]
    walls = json.loads((stopped / seeds.SEEDS_FILE).read_text())["walls"]
    assert [len(walls[seed]) for seed in ("0", "1")] == [2, 2]
    assert seeds.main(["--resume", str(stopped)]) == 0  # nothing left to run
    assert json.loads((stopped / seeds.SEEDS_FILE).read_text())["walls"] == walls
    assert "seed-0:" not in capsys.readouterr().out

    def computed(run_dir: pathlib.Path) -> tuple[list[dict], dict]:
        timing = {"wall_time", "steps_per_second"}
        rows = [{k: v for k, v in row.items() if k not in timing} for row in rundir.read_metrics(run_dir)]
        evaluation = json.loads((run_dir / "eval.json").read_text())
        return rows, {k: v for k, v in evaluation.items() if k not in {"train_wall_time", "eval_wall_time"}}

    assert computed(tmp_path / "whole" / "seed-0") == computed(stopped / "seed-0")
