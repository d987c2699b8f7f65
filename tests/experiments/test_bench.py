"""The benchmarks' arithmetic and options: equal parts, the steady rate, scan lengths, one learner alone (the
runs themselves are benchmarks)."""

import pytest

from experiments.benchmarks import training
from experiments.benchmarks.arm2d import default_max_env_steps, scan_length
from experiments.benchmarks.training import PARTS, Result, ppo_config


def test_steady_rate_skips_the_first_part_and_books_the_rest_as_one_off_costs():
    # brax's pattern: the first two epochs compile, the later ones run at the steady rate.
    result = Result(
        env_steps=4_000, total_seconds=20.0, part_seconds=(7.0, 6.0, 1.0, 2.0), success_rate=1.0, return_mean=0.0
    )
    assert result.train_seconds == pytest.approx(4.0)
    assert result.compile_seconds == pytest.approx(16.0)
    assert result.steps_per_second == pytest.approx(1_000.0)


def test_budget_rounds_up_to_equal_parts():
    config = ppo_config("arm2d", num_envs=64, env_steps=10_000)
    assert config.num_updates % PARTS == 0
    assert config.updates_per_chunk * PARTS == config.num_updates
    assert config.total_env_steps >= 10_000
    assert config.total_env_steps - 10_000 < PARTS * config.env_steps_per_update


def test_arm2d_scan_length_keeps_cpu_calls_short_and_gpu_calls_long():
    cpu, gpu = default_max_env_steps("cpu"), default_max_env_steps("gpu")
    assert scan_length(1 << 20, 1000, cpu) == 19
    assert scan_length(1 << 20, 1000, gpu) == 1000
    assert scan_length(1, 1000, cpu) == 1000
    assert scan_length(1 << 30, 1000, cpu) == 10


def test_one_learner_alone_prints_its_line_and_no_table(capsys):
    training.main(
        ["--env", "arm2d", "--num-envs", "64", "--env-steps", "8192", "--eval-episodes", "4", "--learners", "jaxarm"]
    )
    out = capsys.readouterr().out
    assert "jaxarm PPO:" in out and "env steps/s at the steady rate" in out
    assert "brax PPO" not in out and "| jaxarm PPO | brax PPO |" not in out


def test_ceiling_line_books_each_learner_beyond_the_env_stepping():
    config = ppo_config("arm2d", num_envs=64, env_steps=64 * 16 * PARTS * 10)  # 40 updates
    ours = Result(
        env_steps=config.total_env_steps,
        total_seconds=9.0,
        part_seconds=(3.0, 1.5, 1.5, 1.5),
        success_rate=1.0,
        return_mean=0.0,
    )  # steady 6 s: 150 ms per update
    brax = Result(
        env_steps=config.total_env_steps,
        total_seconds=9.0,
        part_seconds=(3.0, 2.0, 2.0, 2.0),
        success_rate=1.0,
        return_mean=0.0,
    )  # steady 8 s: 200 ms per update
    line = training.ceiling_line(config, ours, brax, env_seconds_per_update=0.125)
    assert "125.0 ms per update" in line
    assert "our learner costs 25.0 ms, brax's 75.0 ms" in line
    assert "would run at 1.60× brax's steady rate; ours runs at 1.33×" in line


def test_env_stepping_alone_is_timed_per_update():
    config = ppo_config("arm2d", num_envs=16, env_steps=16 * 16 * PARTS * 2)
    seconds = training.env_stepping_seconds(config)
    assert 0.0 < seconds < 1.0
