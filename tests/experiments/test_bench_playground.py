"""`bench playground`'s arithmetic and its mapping of Playground's recipe (the runs themselves are benchmarks)."""

import pytest

from experiments.benchmarks.playground import Point, Run, jaxarm_config, main, playground_kwargs, summary_rows, table


def run(learner: str, seed: int, successes: list[float], seconds: list[float], steps: list[int]) -> Run:
    points = tuple(Point(n, t, s, 0.0) for n, t, s in zip(steps, seconds, successes, strict=True))
    return Run("PandaPickCube", learner, seed, points)


def test_the_time_to_the_goal_is_the_first_point_that_reaches_it_and_the_steady_rate_skips_the_first():
    trained = run("jaxarm", 0, [0.0, 0.5, 0.95, 0.9], [10.0, 30.0, 40.0, 50.0], [0, 100, 300, 400])
    assert trained.seconds_to(0.9) == 40.0 and trained.seconds_to(0.99) is None
    assert trained.steady_steps_per_second == pytest.approx(20.0)  # 200 steps in 10 s, not the first interval


def test_rows_give_each_learners_worst_seed_and_the_ratio_of_worst_times():
    runs = [
        run("playground", 0, [0.0, 0.95], [5.0, 100.0], [0, 10]),
        run("playground", 1, [0.0, 0.95], [5.0, 120.0], [0, 10]),
        run("jaxarm", 0, [0.0, 0.95], [5.0, 60.0], [0, 10]),
        run("jaxarm", 1, [0.0, 0.5], [5.0, 60.0], [0, 10]),
    ]
    rows = summary_rows(runs, 0.9)
    assert [(row["learner"], row["worst_seconds_to_goal"]) for row in rows] == [("playground", 120.0), ("jaxarm", None)]
    assert "| PandaPickCube | jaxarm | 60 s, never | never |" in table(rows, 0.9)
    rows[1]["worst_seconds_to_goal"] = 60.0
    assert "over Playground's: 0.50×" in table(rows, 0.9)


def test_playgrounds_recipe_keeps_its_settings_and_how_often_its_envs_reset():
    pytest.importorskip("mujoco_playground", reason="MuJoCo Playground is not installed (the playground extra)")
    kwargs = playground_kwargs("PandaPickCube", "jax", evals=10, num_envs=None, env_steps=None)
    # manipulation_params.py: 4 evaluations (3 after the first) of 10 resets each.
    assert (kwargs["num_evals"], kwargs["num_resets_per_eval"]) == (11, 3)
    assert kwargs["num_timesteps"] == 20_000_000 and kwargs["num_envs"] == 2048 and kwargs["batch_size"] == 512
    assert kwargs["learning_rate"] == 1e-3 and kwargs["run_evals"] is False
    with pytest.raises(
        ValueError, match=r"--evals 7 must divide the 30 resets .* \(one of 1, 2, 3, 5, 6, 10, 15, 30\)"
    ):
        playground_kwargs("PandaPickCube", "jax", evals=7, num_envs=None, env_steps=None)
    small = playground_kwargs("PandaPickCube", "jax", evals=2, num_envs=8, env_steps=640)
    assert (small["num_envs"], small["batch_size"], small["num_timesteps"]) == (8, 2, 640)


def test_evals_that_do_not_divide_playgrounds_resets_are_refused_before_training(capsys):
    pytest.importorskip("mujoco_playground", reason="MuJoCo Playground is not installed (the playground extra)")
    with pytest.raises(SystemExit) as exited:
        main(["--tasks", "PandaPickCube", "--evals", "4"])
    assert exited.value.code == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.splitlines()[-1].endswith(
        "--evals 4 must divide the 30 resets of Playground's "
        "recipe for PandaPickCube (one of 1, 2, 3, 5, 6, 10, 15, 30)"
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--num-envs", "0"], "argument --num-envs: the count must be in [1, 1048576], got 0"),
        (["--env-steps", "-5"], "argument --env-steps: the count must be >= 1, got -5"),
        (["--eval-episodes", "1e9"], "argument --eval-episodes: the count must be in [1, 1048576], got 1000000000"),
        (["--evals", "100000000"], "--evals must be at most 1000, --goal in (0, 1]"),
        (["--impl", "cuda"], "impl must be one of ['jax', 'warp', 'auto'], got 'cuda'"),
        (["learning_rate=-1"], "learning_rate must be in (0, 1], got -1.0"),
    ],
)
def test_bad_settings_are_refused_in_one_line_before_training(argv, message, capsys):
    # Each was a traceback (ZeroDivisionError, an out-of-memory error, ValueError), the first after a training.
    with pytest.raises(SystemExit) as exited:
        main(["--learners", "jaxarm", *argv])
    assert exited.value.code == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.splitlines()[-1].endswith(f"error: {message}")


def test_jaxarms_side_is_the_preset_in_equal_calls():
    pytest.importorskip("mujoco_playground", reason="MuJoCo Playground is not installed (the playground extra)")
    config = jaxarm_config("PandaPickCube", 3, "jax", 10, ["learning_rate=5e-4"], None, None)
    assert config.seed == 3 and config.learning_rate == 5e-4 and dict(config.env_kwargs)["impl"] == "jax"
    assert config.num_updates == 10 * config.updates_per_chunk and config.total_env_steps >= 20_000_000
    assert config.shuffle_groups == 8  # the preset's, where the envs are the preset's
