"""Comparing run directories: curves read back, values at a common wall clock, table, figure, errors."""

import dataclasses
import json
import pathlib

import numpy as np
import pytest

from experiments import compare, configs
from jaxarm.runner import plots, rundir


def write_run(
    run_dir,
    num_envs: int,
    rows: list[tuple[float, float, float, float, float]],
    device=None,
    evaluations: dict[int, float] | None = None,
):
    """A run directory with `ppo_arm2d` at `num_envs` and metric rows of
    (wall_time, steps_per_second, episodes, success_rate, return_mean); `evaluations` maps an update (from 1)
    to the success rate of an evaluation logged with it."""
    preset = configs.get("ppo_arm2d")
    # A time limit of one update's steps, so that rolling means span a twentieth of the rows, at least one.
    config = dataclasses.replace(preset, num_envs=num_envs, env_params=(*preset.env_params, ("max_episode_steps", 16)))
    rundir.write_config(run_dir, config, "ppo_arm2d")
    lines = []
    for update, (wall, rate, episodes, success, returns) in enumerate(rows, start=1):
        row = {
            "updates": update,
            "wall_time": wall,
            "steps_per_second": rate,
            "env_steps": update * num_envs * config.rollout_length,
            "episodes/episodes": episodes,
            "episodes/success_rate": success,
            "episodes/return_mean": returns,
        }
        if update in (evaluations or {}):
            row["eval/success_rate"] = evaluations[update]
        lines.append(json.dumps(row))
    (run_dir / "metrics.jsonl").write_text("\n".join(lines) + "\n")
    if device:
        (run_dir / "eval.json").write_text(json.dumps({"episodes": 100, "success_rate": 0.5, "device": device}))
    return run_dir


def test_a_run_reads_back_with_its_batch_rate_and_episode_weighted_curves(tmp_path):
    rows = [
        (10.0, 100.0, 1, 0.0, -1.0),
        (10.0, 100.0, 0, 0.9, 9.0),
        (12.0, 300.0, 3, 1.0, 3.0),
        (14.0, 500.0, 1, 1.0, 5.0),
    ]
    run = compare.load_run(write_run(tmp_path / "a", 64, rows))
    assert run.label == "a" and run.batch == 64 * 16
    # The update with no finished episode is left out; with 3 rows the rolling window is 1 update.
    np.testing.assert_allclose(run.wall_seconds, [10.0, 12.0, 14.0])
    np.testing.assert_allclose(run.update_seconds, [5.0, 12.0, 14.0])  # the first chunk's two updates: 5 s each
    np.testing.assert_allclose(run.success, [0.0, 1.0, 1.0])
    np.testing.assert_allclose(run.returns, [-1.0, 3.0, 5.0])
    assert run.steps_per_second == 400.0  # median after the first chunk (wall 10 s holds the compilation)
    assert run.evaluation is None
    assert run.eval_success.shape == (0,)
    assert np.isnan(compare.value_at(run, run.success, 9.0))
    assert compare.value_at(run, run.returns, 13.0) == 3.0


def test_training_success_rolls_over_a_time_limit_weighted_by_the_episodes_judged(tmp_path):
    # ppo_arm2d's own time limit, 200 steps: 13 updates of 16 steps per env, more than a twentieth of 20 rows.
    config = configs.get("ppo_arm2d")
    assert config.updates_per_time_limit() == 13
    run_dir = tmp_path / "a"
    rundir.write_config(run_dir, config, "ppo_arm2d")
    # Each update finished 2 episodes, both successes, and judged 8: 6 first episodes still running.
    row = {
        "wall_time": 1.0,
        "steps_per_second": 1.0,
        "episodes/episodes": 2,
        "episodes/judged": 8,
        "episodes/return_mean": 0,
    }
    rows = [{**row, "updates": update, "env_steps": update, "episodes/success_rate": 0.25} for update in range(20)]
    rows[-1].update({"episodes/success_rate": 1.0, "episodes/judged": 2})
    (run_dir / "metrics.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    run = compare.load_run(run_dir)
    np.testing.assert_allclose(run.success[-1], (12 * 2 + 2) / (12 * 8 + 2))  # the last 13 updates' successes


def test_a_sweeps_seeds_roll_their_training_success_each_by_its_own_judged_episodes():
    import warnings

    rates = np.array([[0.0, 1.0, 0.5], [0.0, 0.0, 1.0]])
    judged = np.array([[8.0, 2.0, 2.0], [0.0, 0.0, 4.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rolled = plots.rolling_rates(rates, judged, window=2)
    np.testing.assert_allclose(rolled[0], [0.0, 2 / 10, 3 / 4])
    assert np.isnan(rolled[1][:2]).all() and rolled[1][2] == 1.0, "NaN where a seed's window judged nothing"


def test_each_chunks_updates_are_spread_over_its_seconds_for_curves_over_wall_clock():
    # Chunks of 2, 1 and 3 updates ending at 10, 12 and 18 s (a resumed run's clock goes on the same way).
    chunk_ends = np.array([10.0, 10.0, 12.0, 18.0, 18.0, 18.0])
    np.testing.assert_allclose(compare.update_times(chunk_ends), [5.0, 10.0, 12.0, 14.0, 16.0, 18.0])


def test_the_table_compares_runs_at_the_wall_clock_all_of_them_reached(tmp_path):
    short = write_run(tmp_path / "short", 64, [(10.0, 100.0, 2, 0.2, 1.0), (20.0, 100.0, 2, 0.4, 2.0)], "GPU X")
    long = write_run(
        tmp_path / "long",
        128,
        [(10.0, 100.0, 2, 0.1, 0.5), (20.0, 100.0, 2, 0.3, 1.5), (30.0, 100.0, 2, 0.9, 9.5)],
        "GPU X",
        evaluations={1: 0.25, 2: 0.75, 3: 0.5},
    )
    runs = [compare.load_run(short), compare.load_run(long, "big batch")]
    np.testing.assert_allclose(runs[1].eval_env_steps, [2048.0, 4096.0, 6144.0])
    np.testing.assert_allclose(runs[1].eval_wall_seconds, [10.0, 20.0, 30.0])
    lines = compare.table(runs).splitlines()
    assert "success at 20 s" in lines[0]
    assert lines[3].startswith("| big batch | 2,048 |")
    assert "| 90.0% | 9.5 | 30.0% | 1.5 | 75.0% (4,096, 20) | 50.0% (100) |" in lines[3]
    assert "| — | 50.0% (100) |" in lines[2]
    assert compare.device_name(runs, None) == "GPU X"


def test_a_run_that_logged_nothing_by_the_common_wall_clock_shows_a_dash(tmp_path):
    """A run whose first chunk (its compilation) ended after the other run had finished."""
    quick = write_run(tmp_path / "quick", 64, [(10.0, 100.0, 2, 0.2, 1.0), (20.0, 100.0, 2, 0.4, 2.0)])
    slow = write_run(tmp_path / "slow", 64, [(58.0, 100.0, 2, 0.1, 0.5), (80.0, 100.0, 2, 0.9, 9.5)])
    row = compare.table([compare.load_run(quick), compare.load_run(slow)]).splitlines()[3]
    assert "| 90.0% | 9.5 | — | — | — |" in row and "nan" not in row


def test_the_cli_draws_the_figure_and_names_the_device_or_refuses(tmp_path, capsys):
    first = write_run(tmp_path / "first", 64, [(10.0, 100.0, 2, 0.2, 1.0), (20.0, 100.0, 2, 0.4, 2.0)])
    second = write_run(tmp_path / "second", 64, [(10.0, 100.0, 2, 0.2, 1.0)], evaluations={1: 0.5})
    out = tmp_path / "compare.png"
    assert compare.main([str(first), str(second), "--out", str(out)]) == 2
    assert "--device" in capsys.readouterr().err
    assert compare.main([str(first), str(second), "--label", "only one", "--device", "CPU"]) == 2
    assert "1 --label for 2 runs" in capsys.readouterr().err
    # Runs of one name (seed-0 of two studies) drew one curve, the other left out; told apart, both are drawn.
    twin = write_run(tmp_path / "other" / "first", 64, [(10.0, 100.0, 2, 0.2, 1.0)])
    assert compare.main([str(first), str(twin), "--device", "CPU", "--out", str(out)]) == 2
    assert capsys.readouterr().err == "error: runs share the label 'first'; give each a --label of its own, in order\n"
    assert (
        compare.main([str(first), str(twin), "--device", "CPU", "--out", str(out), "--label", "a", "--label", "b"]) == 0
    )
    assert compare.main([str(first), str(second), "--device", "CPU", "--out", str(out)]) == 0
    assert out.stat().st_size > 0
    assert compare.main([str(tmp_path)]) == 2
    assert "not a run directory" in capsys.readouterr().err
    assert compare.main([str(first), str(second), "--device", "CPU"]) == 0, "compare.png beside the runs"
    assert (tmp_path / "compare.png").exists() and not pathlib.Path("compare.png").exists()


def test_a_named_device_never_relabels_runs_recorded_on_another(tmp_path, capsys):
    on_cpu = write_run(tmp_path / "cpu", 64, [(10.0, 100.0, 2, 0.2, 1.0)], "cpu")
    on_gpu = write_run(tmp_path / "gpu", 64, [(10.0, 100.0, 2, 0.2, 1.0)], "NVIDIA H100 80GB HBM3")
    assert compare.main([str(on_cpu), str(on_gpu), "--device", "NVIDIA H100 80GB"]) == 2
    assert "cpu on 'cpu'" in capsys.readouterr().err
    runs = [compare.load_run(on_gpu)]
    assert compare.device_name(runs, "H100") == "H100", "a part of the recorded name labels it"


def test_a_run_without_finished_episodes_is_an_error(tmp_path):
    with pytest.raises(ValueError, match="no metrics with finished episodes"):
        compare.load_run(write_run(tmp_path / "empty", 64, [(10.0, 100.0, 0, 0.0, 0.0)]))


def test_dollars_in_names_labels_and_titles_are_drawn_as_written(tmp_path):
    # Before: matplotlib took a `$` pair for mathtext and ended in its ParseSyntaxException traceback.
    run = write_run(tmp_path / "run $\\foo{$", 64, [(10.0, 100.0, 2, 0.2, 1.0)])
    out = tmp_path / "compare.png"
    assert compare.main([str(run), "--device", "CPU", "--out", str(out), "--title", "$\\frac$"]) == 0
    assert compare.main([str(run), "--device", "CPU", "--out", str(out), "--label", "a $\\frac{$ b"]) == 0
    assert out.stat().st_size > 0
