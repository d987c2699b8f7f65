"""The benchmarks' arithmetic and options: equal parts, the steady rate, scan lengths, one learner alone, the
JSON record each suite writes beside its markdown (the runs themselves are benchmarks)."""

import dataclasses
import importlib
import json
import math

import jax
import pytest

from experiments.benchmarks import arm2d, camera, devices, learner, record, scaling, training
from experiments.benchmarks.arm2d import default_max_env_steps, scan_length
from experiments.benchmarks.training import PARTS, Result, ppo_config
from jaxarm import envs


def test_steady_rate_skips_the_first_part_and_books_the_rest_as_one_off_costs():
    # brax's pattern: the first two epochs compile, the later ones run at the steady rate.
    result = Result(
        env_steps=4_000,
        total_seconds=20.0,
        part_seconds=(7.0, 6.0, 1.0, 2.0),
        success_rate=1.0,
        return_mean=0.0,
        policy_env_seconds=0.5,
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


def read_record(directory, suite: str, argv: list[str]) -> dict:
    """The suite's JSON record, checked for the fields every suite writes."""
    written = json.loads((directory / f"{suite}.json").read_text())
    assert written["suite"] == suite
    assert written["device"] == jax.devices()[0].device_kind
    assert written["command"] == record.command_line(suite, argv)
    assert written["date"].startswith("20")
    return written


@pytest.mark.slow
def test_one_learner_alone_prints_its_line_and_no_table(capsys, tmp_path):
    argv = ["--env", "arm2d", "--num-envs", "64", "--env-steps", "8192", "--eval-episodes", "4"]
    argv += ["--learners", "jaxarm", "--out", str(tmp_path)]
    training.main(argv)
    out = capsys.readouterr().out
    assert "jaxarm PPO:" in out and "env steps/s at the steady rate" in out
    assert "brax PPO" not in out and "| jaxarm PPO | brax PPO |" not in out
    written = read_record(tmp_path, "training", argv)
    (row,) = written["rows"]
    assert row["learner"] == "jaxarm" and row["env_steps"] == 8192
    assert len(row["part_seconds"]) == training.PARTS and row["steps_per_second"] > 0
    assert 0.0 <= row["success_rate"] <= 1.0
    assert written["ceiling"] == {}  # brax did not run


def test_record_writes_unmeasured_figures_as_null(tmp_path):
    path = record.write_record(tmp_path / "new", "suite", ["--flag", "a b"], [{"rate": math.nan, "envs": 2}])
    written = json.loads(path.read_text())
    assert written["rows"] == [{"rate": None, "envs": 2}]
    assert written["command"] == "python -m experiments.bench suite --flag 'a b'"


@pytest.mark.slow
def test_arm2d_suite_writes_its_table_rows(capsys, tmp_path):
    argv = ["--sizes", "1,16", "--steps", "20", "--out", str(tmp_path)]
    arm2d.main(argv)
    out = capsys.readouterr().out
    written = read_record(tmp_path, "arm2d", argv)
    assert [row["envs"] for row in written["rows"]] == [1, 16]
    for row in written["rows"]:
        assert row["env_steps_per_second"] > 0 and row["env_steps_per_second_without_auto_reset"] > 0
        assert f"| {row['envs']:,} | {row['env_steps_per_second']:,.3g} |" in out
    assert written["numpy_single_env_steps_per_second"] > 0


@pytest.mark.slow
def test_camera_suite_times_the_compile_of_a_pixel_learners_update(capsys, tmp_path):
    argv = ["--envs", "", "--train-configs", "ppo_arm2d_pixels", "--out", str(tmp_path)]
    argv += ["num_envs=2", "rollout_length=2", "num_minibatches=1", "num_epochs=1"]
    camera.main(argv)
    written = read_record(tmp_path, "camera", argv)
    assert written["rows"] == [] and written["update_compile_seconds"]["ppo_arm2d_pixels"] > 0
    assert "| ppo_arm2d_pixels |" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        camera.main(["--envs", "", "--train-configs", "ppo_arm2d_pixels", "num_env=2"])  # a typo


def test_learner_suite_times_the_sgd_phase_per_unroll(tmp_path):
    argv = ["--config", "ppo_arm2d", "--unrolls", "1,0", "--repeats", "1", "--out", str(tmp_path)]
    argv += ["num_envs=16", "rollout_length=8", "num_minibatches=4", "num_epochs=2"]
    learner.main(argv)
    written = read_record(tmp_path, "learner", argv)
    assert [row["unroll"] for row in written["rows"]] == [1, 0]
    assert all(row["sgd_ms"] > 0 for row in written["rows"])
    assert written["sgd_steps"] == 8 and written["minibatch_size"] == 32
    with pytest.raises(SystemExit):
        learner.main(["--config", "td3_arm2d"])  # not a PPO preset


def test_random_samples_take_the_envs_shapes_and_frames_stay_uint8():
    spec = envs.make("arm2d", obs_mode="pixels").spec
    samples = learner.random_samples(jax.random.PRNGKey(0), spec, 3, 5)
    image = samples.obs["image"]
    assert image.dtype == jax.numpy.uint8 and image.shape == (3, 5, *spec.observation["image"].shape)
    assert samples.raw_action.shape == (3, 5, spec.action_size) and samples.target.shape == (3, 5)


@pytest.mark.slow
def test_scaling_suite_writes_its_curves(tmp_path):
    argv = ["--envs", "arm2d", "--env-sizes", "1,16", "--ppo-sizes", "16", "--quick"]
    argv += ["--plot", str(tmp_path / "scaling.png"), "--out", str(tmp_path)]
    scaling.main(argv)
    written = read_record(tmp_path, "scaling", argv)
    assert [(row["measurement"], row["envs"]) for row in written["rows"]] == [
        ("env stepping", 1),
        ("env stepping", 16),
        ("PPO training", 16),
    ]
    assert all(row["env_steps_per_second"] > 0 for row in written["rows"])
    assert written["breakdown_at_preset"] == {}  # the preset's 1,024 envs were not reached
    assert (tmp_path / "scaling.png").exists()


@pytest.mark.slow
def test_devices_suite_scales_the_env_batch_and_times_training_to_a_target(tmp_path):
    scaled = devices.scaled_config("ppo_sorter", 4, None, "jax")
    assert scaled.num_envs == 4 * 8192 and dict(scaled.env_kwargs)["max_envs"] == 8192  # one device's share
    assert dict(scaled.env_kwargs)["impl"] == "jax"
    argv = ["--configs", "ppo_arm2d", "--devices", "1,2", "--envs-per-device", "16", "--updates", "1"]
    argv += ["--train-to", "0.0", "--eval-every", "1", "--train-minutes", "0", "--out", str(tmp_path)]
    devices.main(argv)
    written = read_record(tmp_path, "devices", argv)
    assert [(row["devices"], row["envs"]) for row in written["rows"]] == [(1, 16)]  # one CPU device here
    assert written["rows"][0]["env_steps_per_second"] > 0 and written["rows"][0]["over_first"] == 1.0
    (trained,) = written["trainings"]
    assert trained["seconds_to_target"] is not None and trained["env_steps_to_target"] > 0


def test_breakdown_at_the_preset_books_every_phase_of_an_update():
    config = dataclasses.replace(ppo_config("arm2d", num_envs=16, env_steps=16 * 16 * PARTS), num_minibatches=2)
    phases = dict(scaling.time_breakdown(config, num_updates=2))
    assert phases["whole update"] > 0
    sgd = next(ms for phase, ms in phases.items() if phase.startswith("normaliser update"))
    assert sgd > 0  # the learning is the bulk of an arm2d update on the CPU


def test_ceiling_line_books_each_learner_beyond_the_env_stepping():
    config = ppo_config("arm2d", num_envs=64, env_steps=64 * 16 * PARTS * 10)  # 40 updates
    ours = Result(
        env_steps=config.total_env_steps,
        total_seconds=9.0,
        part_seconds=(3.0, 1.5, 1.5, 1.5),
        success_rate=1.0,
        return_mean=0.0,
        policy_env_seconds=0.140,
    )  # steady 6 s: 150 ms per update
    brax = Result(
        env_steps=config.total_env_steps,
        total_seconds=9.0,
        part_seconds=(3.0, 2.0, 2.0, 2.0),
        success_rate=1.0,
        return_mean=0.0,
        policy_env_seconds=0.160,
    )  # steady 8 s: 200 ms per update
    line = training.ceiling_line(config, ours, brax, env_seconds_per_update=0.125)
    assert "125.0 ms per update" in line
    assert "our learner costs 25.0 ms, brax's 75.0 ms" in line
    assert "would run at 1.60× brax's steady rate; ours runs at 1.33×" in line
    # Under the trained policies the physics costs more: 140 and 160 ms.
    assert "beyond it our learner costs 10.0 ms, brax's 40.0 ms" in line
    assert "as ours drives them, would run at 1.43× brax" in line


def test_env_stepping_under_a_policy_takes_the_policys_actions():
    config = ppo_config("arm2d", num_envs=16, env_steps=16 * 16 * PARTS * 2)
    calls = []

    def policy(obs):
        calls.append(obs.shape)  # traced once, inside the scan
        return jax.numpy.zeros((obs.shape[0], 2))

    seconds = training.env_stepping_seconds(config, policy)
    assert 0.0 < seconds < 1.0
    assert calls == [(16, config.make_env()[0].spec.observation_size)]


def test_overrides_change_the_preset_both_learners_map_from():
    config = ppo_config("arm2d", num_envs=64, env_steps=10_000, overrides=("anneal_learning_rate=false",))
    assert not config.anneal_learning_rate
    assert training.brax_ppo_kwargs(config, 1e-3)["num_minibatches"] == config.num_minibatches
    with pytest.raises(ValueError, match="unknown config key"):
        ppo_config("arm2d", num_envs=64, env_steps=10_000, overrides=("anneal_learnig_rate=false",))


def test_env_stepping_alone_is_timed_per_update():
    config = ppo_config("arm2d", num_envs=16, env_steps=16 * 16 * PARTS * 2)
    seconds = training.env_stepping_seconds(config)
    assert 0.0 < seconds < 1.0


@pytest.mark.parametrize("suite", [arm2d, camera, scaling])
@pytest.mark.parametrize(
    ("sizes", "said"),
    [
        ("0", "each env count must be in [1, 1048576], got 0"),
        ("-8", "each env count must be in [1, 1048576], got -8"),
        ("1e11", "each env count must fit in int32 (at most 2,147,483,647 in magnitude), got 100,000,000,000"),
        ("1,x", "expected an integer, got 'x'"),
        (",", "expected comma-separated env counts, got ','"),
    ],
)
def test_suites_refuse_env_counts_out_of_range_in_one_line_before_timing(suite, sizes, said, capsys, tmp_path):
    flag = "--env-sizes" if suite is scaling else "--sizes"
    with pytest.raises(SystemExit) as exited:
        suite.main([flag, sizes, "--out", str(tmp_path)])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].endswith(f"error: argument {flag}: {said}")
    assert "Traceback" not in err


def test_arm2d_suite_refuses_a_scan_of_no_steps(capsys):
    with pytest.raises(SystemExit):
        arm2d.main(["--unroll", "0"])
    assert capsys.readouterr().err.splitlines()[-1].endswith("argument --unroll: the count must be >= 1, got 0")


@pytest.mark.parametrize(
    ("suite", "flag"),
    [("deploy", "--ticks"), ("ceilings", "--seeds"), ("profile", "--updates"), ("devices", "--updates")],
)
def test_suites_refuse_a_count_of_zero_before_timing(suite, flag, capsys):
    # Before: deploy --ticks 0 an IndexError, ceilings --seeds 0 numpy's "Need at least one array to stack".
    module = importlib.import_module(f"experiments.benchmarks.{suite}")
    with pytest.raises(SystemExit):
        module.main([flag, "0"])
    assert capsys.readouterr().err.splitlines()[-1].endswith(f"argument {flag}: the count must be >= 1, got 0")
