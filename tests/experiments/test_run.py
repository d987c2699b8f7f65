"""The runner end to end: files of a run, CLI errors, resume after SIGKILL, NaN stop, bad checkpoints."""

import dataclasses
import errno
import io
import json
import os
import pathlib
import signal
import subprocess
import sys
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments import configs, run
from experiments import eval as eval_cli
from jaxarm import envs
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import apply_overrides
from jaxarm.agents.ppo.warm_start import warm_start
from jaxarm.runner import learners, loop, metrics_log, robustness, rundir, runlog, tries

SMALL = [
    "num_envs=64",
    "rollout_length=16",
    "num_minibatches=2",
    "total_env_steps=24576",
    "updates_per_chunk=4",
    "checkpoint_every_updates=4",
    "eval_episodes=20",
    "eval_every_updates=0",  # the final evaluation alone, unless a test asks for more
]


def run_cli(*args):
    return run.main(["--config", "ppo_arm2d_fixed", *args])


def final_params(run_dir: pathlib.Path):
    config, _ = rundir.read_config(run_dir)
    return learners.restore_state(run_dir, learners.make_trainer(config), config)


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("runs") / "full"
    assert run_cli(*SMALL, "--out", str(run_dir)) == 0
    return run_dir


def test_a_run_writes_config_metrics_checkpoints_curve_and_eval(finished_run):
    config = json.loads((finished_run / "config.json").read_text())
    assert config["preset"] == "ppo_arm2d_fixed" and config["num_envs"] == 64
    rows = metrics_log.read_metrics(finished_run)
    assert [row["updates"] for row in rows] == list(range(1, 25))
    assert {
        "env_steps",
        "episodes/return_mean",
        "episodes/success_rate",
        "loss/policy_loss",
        "steps_per_second",
        "wall_time",
    } <= set(rows[0])
    assert checkpoint.latest_step(finished_run / "checkpoints") == 24
    assert (finished_run / "curve.png").stat().st_size > 10_000
    assert any((finished_run / "tensorboard").iterdir())
    result = json.loads((finished_run / "eval.json").read_text())
    assert result["episodes"] == 20 and 0.0 <= result["success_rate"] <= 1.0 and "return_mean" in result


def test_evaluation_runs_on_the_eval_env_params_and_reports_the_final_info(tmp_path):
    run_dir = tmp_path / "eval_params"
    assert run_cli(*SMALL, "eval_env_params.max_episode_steps=7", "--out", str(run_dir)) == 0
    config, _ = rundir.read_config(run_dir)
    assert dict(config.eval_env_params) == {"max_episode_steps": 7}
    assert int(config.make_env()[1].max_episode_steps) == 200, "training keeps its own params"
    result = json.loads((run_dir / "eval.json").read_text())
    assert result["length_mean"] <= 7
    assert any(name.startswith("final_info/") for name in result)


@pytest.mark.slow
def test_eval_cli_writes_its_own_file_keeps_eval_json_and_draws_a_video(finished_run):
    training_eval = (finished_run / "eval.json").read_text()
    assert eval_cli.main([str(finished_run), "--episodes", "7", "--video"]) == 0
    assert json.loads((finished_run / "eval-7-12345-24.json").read_text())["episodes"] == 7
    assert (finished_run / "eval.json").read_text() == training_eval
    assert (finished_run / "video.gif").stat().st_size > 1000


def test_an_evaluation_is_written_before_it_is_printed(finished_run, monkeypatch, capsys):
    class Gone(io.StringIO):  # the output of `python -m experiments.eval RUN | head -1`, once head has gone
        def write(self, text):
            raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

    monkeypatch.setattr(sys, "stdout", Gone())
    assert eval_cli.main([str(finished_run), "--episodes", "6"]) == 2
    assert json.loads((finished_run / "eval-6-12345-24.json").read_text())["episodes"] == 6
    assert capsys.readouterr().err.startswith("error: Broken pipe; the output's reader went away (as `| head` does)")


COUNT_CACHE_EVENTS = """
import collections, json, sys
import jax
from experiments import eval as eval_cli
counts = collections.Counter()
jax.monitoring.register_event_listener(lambda event, **kwargs: counts.update([event.rsplit("/", 1)[-1]]))
assert eval_cli.main(sys.argv[1:]) == 0
print(json.dumps(counts))
"""


def test_a_second_eval_compiles_nothing(finished_run):
    """Each `experiments.eval` in a process of its own, as a user runs it, sharing the session's cache: the
    second finds everything it compiles there (hits, no miss)."""

    def cache_events(*args):
        command = [sys.executable, "-c", COUNT_CACHE_EVENTS, str(finished_run), "--episodes", "20", *args]
        done = subprocess.run(command, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout.strip().splitlines()[-1])

    cache_events()
    second = cache_events("--seed", "3")
    assert second["cache_hits"] >= 1 and second.get("cache_misses", 0) == 0


def test_a_run_without_a_terminal_logs_a_progress_line_per_chunk(tmp_path, capsys):
    assert run_cli(*SMALL, "--out", str(tmp_path / "logged")) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("env steps ")]
    assert len(lines) == 6, "24 updates in chunks of 4"
    assert lines[0].startswith("env steps 4,096/24,576 (17%)")
    assert lines[-1].startswith("env steps 24,576/24,576 (100%)") and lines[-1].endswith("ETA 0:00:00")
    assert all("steps/s  return " in line and "  success " in line and " elapsed " in line for line in lines)


def test_cli_errors_are_one_line_and_name_the_closest(capsys, tmp_path):
    assert run.main(["--config", "ppo_arm2dd"]) == 2
    assert "did you mean 'ppo_arm2d'" in capsys.readouterr().err
    assert run_cli("learnin_rate=1", "--out", str(tmp_path / "a")) == 2
    assert "did you mean 'learning_rate'" in capsys.readouterr().err
    assert run_cli("num_envs=-3", "--out", str(tmp_path / "b")) == 2
    assert "num_envs must be in [1, 1048576], got -3" in capsys.readouterr().err
    assert run_cli("gamma=high", "--out", str(tmp_path / "c")) == 2
    assert "bad value for gamma" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()
    with pytest.raises(SystemExit) as exited:  # --out was left aside without a word, the run in RUN resumed
        run.main(["--resume", str(tmp_path / "run"), "--out", str(tmp_path / "elsewhere")])
    assert exited.value.code == 2 and "give no --out" in capsys.readouterr().err
    for wandb in (["--wandb", ""], ["--wandb-offline"]):
        with pytest.raises(SystemExit) as exited:
            run.main(["--config", "ppo_arm2d", *wandb])
        assert exited.value.code == 2 and "--wandb takes a project's name" in capsys.readouterr().err


@pytest.mark.slow
def test_resume_after_sigkill_matches_an_uninterrupted_run(finished_run, tmp_path):
    run_dir = tmp_path / "killed"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    command = [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d_fixed", *SMALL, "--out", str(run_dir)]
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 240
    while time.time() < deadline and (checkpoint.latest_step(run_dir / "checkpoints") or 0) < 8:
        time.sleep(0.2)
    process.send_signal(signal.SIGKILL)
    process.wait()
    killed_at = checkpoint.latest_step(run_dir / "checkpoints")
    assert killed_at is not None and killed_at < 24, "the run finished before it could be killed"
    assert run.main(["--resume", str(run_dir)]) == 0
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 25))
    for resumed, uninterrupted in zip(
        jax.tree.leaves(final_params(run_dir)), jax.tree.leaves(final_params(finished_run)), strict=True
    ):
        np.testing.assert_array_equal(resumed, uninterrupted)


GATED = ["eval_every_updates=4", "retry_below=1.0", "retry_at_env_steps=8192", "tries=2"]
"""A gate SMALL's runs fail at update 8 (their evaluations are below 100% there), with one try after it."""


@pytest.fixture(scope="module")
def retried_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("runs") / "retried"
    assert run_cli(*SMALL, *GATED, "--out", str(run_dir)) == 0
    return run_dir


def test_a_try_below_its_gate_is_set_aside_and_the_run_starts_again_with_fresh_randomness(retried_run):
    set_aside = retried_run / tries.TRIES_DIR / "0"
    failed = metrics_log.read_metrics(set_aside)
    assert [row["updates"] for row in failed] == list(range(1, 9))
    assert max(row["eval/success_rate"] for row in failed if "eval/success_rate" in row) < 1.0
    assert checkpoint.latest_step(set_aside / "checkpoints") == 4 and (set_aside / "best.json").exists()
    rows = metrics_log.read_metrics(retried_run)
    # The last try trains to its end whatever it scores.
    assert [row["updates"] for row in rows] == list(range(1, 25))
    assert rows[0]["loss/policy_loss"] != failed[0]["loss/policy_loss"]
    assert rows[0]["wall_time"] > failed[-1]["wall_time"], "the failed try's time was not counted"
    result = json.loads((retried_run / "eval.json").read_text())
    assert result["tries"] == 2 and result["finished"]
    assert [entry["event"] for entry in json.loads((retried_run / rundir.PROVENANCE_FILE).read_text())["records"]] == [
        "start",
        "try 2",
    ]


def test_a_run_stopped_in_its_second_try_resumes_in_it_bit_identically(retried_run, tmp_path, capsys):
    run_dir = tmp_path / "stopped"
    # Each command stops after its first chunk: try 1's updates 1-4, then 5-8 and its gate, then try 2's first.
    assert run_cli(*SMALL, *GATED, "--out", str(run_dir), "--stop-after-minutes", "0") == 0
    assert run.main(["--resume", str(run_dir), "--stop-after-minutes", "0"]) == 0
    assert "try 1 of 2 failed its gate (best evaluation" in capsys.readouterr().err
    assert checkpoint.latest_step(run_dir / "checkpoints") == 4 and tries.tries_set_aside(run_dir) == 1
    assert run.main(["--resume", str(run_dir)]) == 0
    assert tries.tries_set_aside(run_dir) == 1
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 25))
    for resumed, uninterrupted in zip(
        jax.tree.leaves(final_params(run_dir)), jax.tree.leaves(final_params(retried_run)), strict=True
    ):
        np.testing.assert_array_equal(resumed, uninterrupted)


TRAIN_GATED = [
    "eval_every_updates=4",
    "retry_below=0.01",
    "retry_at_env_steps=20480",
    "retry_train_below=1.0",
    "retry_train_at_env_steps=16384",
    "tries=2",
]
"""An earlier gate on the training episodes that SMALL's runs fail at update 16 (they have not all succeeded by
then); the evaluations' gate, at update 20, asks next to nothing."""


def test_a_try_below_its_training_episodes_gate_is_set_aside_reading_its_last_time_limit(tmp_path, capsys):
    run_dir = tmp_path / "train-gated"
    # Stopped after its first chunk (updates 1-4), resumed: the gate at update 16 reads rows from both commands.
    assert run_cli(*SMALL, *TRAIN_GATED, "--out", str(run_dir), "--stop-after-minutes", "0") == 0
    assert run.main(["--resume", str(run_dir)]) == 0
    config, _ = rundir.read_config(run_dir)
    window = config.updates_per_time_limit()
    assert 12 < window < 16, "a window across the resume, inside the try"
    failed = metrics_log.read_metrics(run_dir / tries.TRIES_DIR / "0")
    assert [row["updates"] for row in failed] == list(range(1, 17))
    rate = tries.training_success(failed[-window:])
    assert rate < 1.0
    assert (
        f"try 1 of 2 failed its gate (training episodes {rate:.2%} over the {window} updates to 16,384 env steps; "
        "it asks 100.00% by 16,384)"
    ) in capsys.readouterr().err
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 25))
    assert json.loads((run_dir / "eval.json").read_text())["tries"] == 2


def test_training_success_weighs_each_update_by_its_judged_episodes():
    rows = [
        {"episodes/success_rate": 0.5, "episodes/judged": 2.0},
        {"episodes/success_rate": 0.0, "episodes/judged": 6.0},
        {"episodes/success_rate": 1.0, "episodes/judged": 0.0},
    ]
    assert tries.training_success(rows) == 1 / 8
    assert tries.training_success(rows[2:]) == 0.0


def test_nan_stops_the_run_naming_the_update_and_keeps_the_last_good_checkpoint(finished_run, tmp_path, capsys):
    config, preset = rundir.read_config(finished_run)
    good = final_params(finished_run)
    # Configs refuse NaN; a reward scale this large makes the first value loss of update 25 overflow to inf.
    diverging = dataclasses.replace(config, reward_scale=1e30, total_env_steps=2 * config.total_env_steps)
    with pytest.raises(loop.TrainingDiverged, match=r"update 25 .*last good checkpoint \(update 24\)"):
        loop.train(diverging, finished_run, preset=preset, resume=True)
    assert checkpoint.latest_step(finished_run / "checkpoints") == 24
    for kept, before in zip(jax.tree.leaves(final_params(finished_run)), jax.tree.leaves(good), strict=True):
        np.testing.assert_array_equal(kept, before)


def test_corrupt_or_mismatched_checkpoint_gives_a_clear_error(finished_run, tmp_path, capsys):
    mismatched = tmp_path / "mismatched"
    mismatched.mkdir()
    config = json.loads((finished_run / "config.json").read_text())
    (mismatched / "config.json").write_text(json.dumps({**config, "policy_hidden_sizes": [8]}))
    (mismatched / "checkpoints").mkdir()
    for step in (finished_run / "checkpoints").iterdir():  # the checkpoints alone, not the config they record
        if step.name.isdigit():
            os.symlink(step, mismatched / "checkpoints" / step.name)
    assert run.main(["--resume", str(mismatched)]) == 2
    assert "cannot be restored" in capsys.readouterr().err or "does not match" in capsys.readouterr().err

    corrupt = tmp_path / "corrupt"
    (corrupt / "checkpoints" / "4").mkdir(parents=True)
    (corrupt / "config.json").write_text((finished_run / "config.json").read_text())
    (corrupt / "checkpoints" / "4" / "garbage").write_text("not a checkpoint")
    assert eval_cli.main([str(corrupt), "--episodes", "2"]) == 2
    assert "error:" in capsys.readouterr().err
    assert not (corrupt / "eval.json").exists() and not list(corrupt.glob("eval-*.json"))


def test_an_empty_checkpoint_folder_is_named_with_the_checkpoint_before_it(tmp_path, capsys):
    # Before: orbax's "Must provide `args` of type `Composite` ..." as the reason, naming no folder.
    run_dir = tmp_path / "stopped"
    assert run_cli(*SMALL, "--out", str(run_dir), "--stop-after-minutes", "0") == 0
    (run_dir / "checkpoints" / "8").mkdir()
    rows = (run_dir / "metrics.jsonl").read_bytes()
    capsys.readouterr()
    assert run.main(["--resume", str(run_dir)]) == 2
    assert eval_cli.main([str(run_dir), "--episodes", "2"]) == 2
    said = f"error: {run_dir}/checkpoints/8 is an empty folder: not a checkpoint; move it out of {run_dir}/checkpoints"
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert errors == [f"{said} to go on from checkpoint 4"] * 2
    assert (run_dir / "metrics.jsonl").read_bytes() == rows
    (run_dir / "checkpoints" / "8").rmdir()
    assert run.main(["--resume", str(run_dir), "--stop-after-minutes", "0"]) == 0
    assert checkpoint.latest_step(run_dir / "checkpoints") == 8


def test_a_time_limit_counts_the_time_before_the_first_chunk(tmp_path):
    # A minute's limit whose clock started 61 s ago, as when a command's stages and compilations took its time: the
    # run stops after its first chunk. Before, each chunk loop started a clock of its own, and a pixel run given
    # 575 s went on past its machine's 600 s limit, its compilations uncounted.
    config = apply_overrides(configs.get("ppo_arm2d_fixed"), SMALL)
    late = loop.Options(stop_after_s=60.0, clock_start=time.perf_counter() - 61.0)
    assert not loop.train(config, tmp_path / "late", options=late)["finished"]
    assert checkpoint.latest_step(tmp_path / "late" / "checkpoints") == 4
    with pytest.raises(ValueError, match="has not started"):
        loop.Options(stop_after_s=60.0).out_of_time()


def test_evaluation_reads_the_policy_alone_and_still_refuses_another_one(finished_run, tmp_path, capsys):
    """The eval CLI restores the state for acting: a config with other envs (num_envs) evaluates the same policy,
    one with other networks is refused as a resume is."""

    def with_config(name: str, **changes) -> pathlib.Path:
        run_dir = tmp_path / name
        (run_dir / "checkpoints").mkdir(parents=True)
        config = json.loads((finished_run / "config.json").read_text())
        (run_dir / "config.json").write_text(json.dumps({**config, **changes}))
        for step in (finished_run / "checkpoints").iterdir():
            if step.name.isdigit():
                os.symlink(step, run_dir / "checkpoints" / step.name)
        return run_dir

    assert eval_cli.main([str(with_config("more_envs", num_envs=64)), "--episodes", "3"]) == 0
    assert eval_cli.main([str(with_config("other_networks", policy_hidden_sizes=[8])), "--episodes", "3"]) == 2
    assert "cannot be restored" in capsys.readouterr().err


@pytest.mark.slow
def test_a_warm_start_begins_from_the_trained_networks_and_statistics(finished_run, tmp_path, capsys):
    config, _ = rundir.read_config(finished_run)
    trained = final_params(finished_run)
    warm = dataclasses.replace(config, init_from=str(finished_run))
    trainer = learners.make_trainer(warm)
    fresh = jax.jit(trainer.init)(jax.random.PRNGKey(5), warm.hparams())
    started = learners.warm_starter(warm, pathlib.Path(warm.init_from))(fresh)
    for copied, source in zip(
        jax.tree.leaves((started.params, started.normalizer)),
        jax.tree.leaves((trained.params, trained.normalizer)),
        strict=True,
    ):
        np.testing.assert_array_equal(copied, source)
    assert int(started.updates) == 0
    for kept, new in zip(jax.tree.leaves(started.opt_state), jax.tree.leaves(fresh.opt_state), strict=True):
        np.testing.assert_array_equal(kept, new)

    # An input the trained learner never saw gets zero weight: at its (normalised) mean the policy is unchanged.
    index = np.arange(9)
    index[4] = -1
    partial = warm_start(warm, config, fresh, trained, index, np.zeros(9, np.float32))
    obs = jax.random.normal(jax.random.PRNGKey(6), (32, 9))
    obs = obs.at[:, 4].set(trained.normalizer.mean[4])
    np.testing.assert_allclose(trainer.act(partial, obs), trainer.act(trained, obs), atol=1e-5)
    # An input that reads more than its source in the same situation acts as the source did there.
    shift = np.zeros(9, np.float32)
    shift[2] = 3.0
    moved = warm_start(warm, config, fresh, trained, np.arange(9), shift)
    np.testing.assert_allclose(trainer.act(moved, obs + shift), trainer.act(trained, obs), atol=1e-5)

    assert run_cli(*SMALL, f"init_from={finished_run}", "--out", str(tmp_path / "warm")) == 0
    assert run_cli(*SMALL, f"init_from={tmp_path / 'nowhere'}", "--out", str(tmp_path / "cold")) == 2
    assert "not a run directory" in capsys.readouterr().err
    assert not (tmp_path / "cold" / "config.json").exists(), "a failed warm start left a run behind"


def test_a_randomised_run_reports_nominal_and_randomised_evaluations(tmp_path):
    run_dir = tmp_path / "randomised"
    assert run_cli(*SMALL, "randomize.action_scale=0.5..1.5", "--out", str(run_dir)) == 0
    config, _ = rundir.read_config(run_dir)
    assert dict(config.randomize) == {"action_scale": "0.5..1.5"}
    result = json.loads((run_dir / "eval.json").read_text())
    assert {"success_rate", "randomized/success_rate", "randomized/return_mean"} <= set(result)
    assert result["randomized/return_mean"] != result["return_mean"]


def robustness_stem(run_dir: pathlib.Path, episodes: int, request: list[str]) -> pathlib.Path:
    """Where `eval --perturb` writes the table of `request` of `finished_run`'s latest checkpoint (update 24)."""
    return rundir.robustness_stem(run_dir, episodes, 12345, "24", request)


def test_robustness_rows_vmap_each_params_values_and_match_the_nominal(finished_run, capsys):
    request = ["action_scale=0.1,0.002", "goal_size=0.05"]
    assert eval_cli.main([str(finished_run), "--episodes", "12", "--perturb", *request]) == 0
    stem = robustness_stem(finished_run, 12, request)
    table = json.loads(stem.with_suffix(".json").read_text())
    # What a study of seeds matches a table by: the request, its episodes and the checkpoint evaluated.
    assert (table["perturb"], table["episodes"], table["checkpoint"]) == (request, 12, "24")
    rows = table["rows"]
    assert [(row["param"], row["value"]) for row in rows] == [
        ("nominal", None),
        ("action_scale", 0.1),
        ("action_scale", 0.002),
        ("goal_size", 0.05),
    ]
    nominal, same, frozen, _ = rows
    # action_scale 0.1 is the nominal value: the vmapped program reproduces the nominal episodes exactly.
    assert same["return_mean"] == nominal["return_mean"] and same["success_rate"] == nominal["success_rate"]
    # An arm that barely moves reaches only goals it starts on.
    assert frozen["success_rate"] < 0.5 * nominal["success_rate"] and frozen["return_mean"] < nominal["return_mean"]
    assert "| action_scale | 0.002 |" in stem.with_suffix(".md").read_text()
    assert stem.with_suffix(".png").stat().st_size > 1000


def test_robustness_rows_of_params_changed_together(finished_run):
    request = ["action_scale=0.002", "action_scale=0.1+goal_size=40", "action_scale=0.002+goal_size=30"]
    assert eval_cli.main([str(finished_run), "--episodes", "12", "--perturb", *request]) == 0
    stem = robustness_stem(finished_run, 12, request)
    table = json.loads(stem.with_suffix(".json").read_text())
    # What a study of seeds matches a table by: the request, its episodes and the checkpoint evaluated.
    assert (table["perturb"], table["episodes"], table["checkpoint"]) == (request, 12, "24")
    rows = table["rows"]
    assert [(row["param"], row["value"]) for row in rows] == [
        ("nominal", None),
        ("action_scale", 0.002),
        ("action_scale=0.1+goal_size=40", None),
        ("action_scale=0.002+goal_size=30", None),
    ]
    nominal, frozen, same, frozen_smaller = rows
    # Both nominal values together reproduce the nominal episodes; a frozen arm with smaller goals reaches few.
    assert same["return_mean"] == nominal["return_mean"] and same["success_rate"] == nominal["success_rate"]
    assert max(frozen["success_rate"], frozen_smaller["success_rate"]) < 0.5 * nominal["success_rate"]
    assert "| action_scale=0.002+goal_size=30 |  |" in stem.with_suffix(".md").read_text()


def test_combined_changes_alone_draw_their_plot_without_a_warning(finished_run):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert eval_cli.main([str(finished_run), "--episodes", "4", "--perturb", "action_scale=0.1+goal_size=40"]) == 0
    assert robustness_stem(finished_run, 4, ["action_scale=0.1+goal_size=40"]).with_suffix(".png").stat().st_size > 0


def test_a_runs_randomised_ranges_give_their_ends():
    params = envs.make("panda_sort").default_params()
    ends = robustness.range_ends({"action_latency": "0..2.5", "mass_scale": "log:0.5..3"}, params)
    assert ends == {"action_latency": [0, 2], "mass_scale": [0.5, 3.0]}


def test_the_worst_corner_takes_each_params_end_that_placed_less():
    rows = [
        {"param": "nominal", "value": None, "success_rate": 0.9, "return_mean": 5.0},
        {"param": "mass_scale", "value": 0.5, "success_rate": 0.8, "return_mean": 4.0},
        {"param": "mass_scale", "value": 3.0, "success_rate": 0.6, "return_mean": 4.0},
        {"param": "friction", "value": 0.6, "success_rate": 0.7, "return_mean": 2.0},
        {"param": "friction", "value": 1.4, "success_rate": 0.7, "return_mean": 3.0},  # a tie: the lower return
        {"param": "friction", "value": 1.0, "success_rate": 0.1, "return_mean": 0.0},  # not an end
    ]
    ends = {"mass_scale": [0.5, 3.0], "friction": [0.6, 1.4]}
    assert robustness.worst_corner(rows, ends) == {"mass_scale": 3.0, "friction": 0.6}
    with pytest.raises(robustness.PerturbationError, match="goal_size"):
        robustness.worst_corner(rows, {"goal_size": [1.0, 2.0]})


def test_the_worst_corner_of_a_randomised_run_is_evaluated_as_that_change_together(tmp_path):
    run_dir = tmp_path / "randomised"
    ranges = ["randomize.action_scale=0.002..0.1", "randomize.goal_size=10..40"]
    assert run_cli(*SMALL, *ranges, "--out", str(run_dir)) == 0
    assert eval_cli.main([str(run_dir), "--episodes", "12", "--worst-corner"]) == 0
    stem = robustness_stem(run_dir, 12, ["--worst-corner"])
    rows = json.loads(stem.with_suffix(".json").read_text())["rows"]
    assert [(row["param"], row["value"]) for row in rows[:5]] == [
        ("nominal", None),
        ("action_scale", 0.002),
        ("action_scale", 0.1),
        ("goal_size", 10.0),
        ("goal_size", 40.0),
    ]
    corner = robustness.worst_corner(rows[:5], {"action_scale": [0.002, 0.1], "goal_size": [10.0, 40.0]})
    label = robustness.combined_label(corner)
    assert rows[5]["param"] == f"{robustness.WORST_CORNER}: {label}" and len(rows) == 6
    # The same change asked for by hand evaluates the same episodes to the same figures.
    assert eval_cli.main([str(run_dir), "--episodes", "12", "--perturb", label]) == 0
    by_hand = json.loads(robustness_stem(run_dir, 12, [label]).with_suffix(".json").read_text())["rows"][1]
    assert (by_hand["success_rate"], by_hand["return_mean"]) == (rows[5]["success_rate"], rows[5]["return_mean"])


def test_the_ends_of_no_randomisation_are_refused_before_the_checkpoint_loads(finished_run, capsys, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("evaluated a run before checking that it randomises anything")

    monkeypatch.setattr(eval_cli, "evaluate_run", never)
    for flag in ("--randomized-ends", "--worst-corner"):
        assert eval_cli.main([str(finished_run), "--episodes", "4", flag]) == 2
        assert capsys.readouterr().err == f"error: {flag}: the run randomises no env param\n"


@pytest.mark.parametrize(
    ("perturb", "message"),
    [
        ("action_scale", "NAME=V1,V2"),
        ("action_scale=fast", "NAME=V1,V2"),
        ("action_scael=0.1", "action_scale"),
        ("action_scale=0", "must be > 0"),
        ("max_episode_steps=5", "rollout's length"),
        ("action_scale=0.1,0.2+goal_size=40", "one value each"),
        ("action_scale=0.1+action_scale=0.2", "each name once"),
        ("action_scale=0.1+goal_size=-1", "goal_size"),
    ],
)
def test_bad_perturbations_are_refused_in_one_line(finished_run, capsys, perturb, message):
    assert eval_cli.main([str(finished_run), "--episodes", "4", "--perturb", perturb]) == 2
    assert message in capsys.readouterr().err


def test_perturbations_that_would_step_too_many_envs_at_once_are_refused(finished_run, capsys):
    # Before: 3,000 values x 1,000 episodes stepped 3e6 envs in one program (minutes; more ran out of memory).
    values = ",".join(f"{0.01 + index * 1e-4:.4f}" for index in range(300))
    argv = [str(finished_run), "--episodes", "4000", "--perturb", f"action_scale={values}"]
    assert eval_cli.main(argv) == 2
    assert capsys.readouterr().err == (
        "error: --perturb: 300 values of action_scale x 4,000 episodes step 1,200,000 envs at once, more than an "
        "evaluation may (in [1, 1048576]); give fewer values or --episodes\n"
    )


def test_a_ten_billion_step_budget_runs_resumes_and_counts_past_int32(tmp_path):
    run_dir = tmp_path / "long"
    long_budget = ["total_env_steps=10000000000", "--out", str(run_dir), "--stop-after-minutes", "0"]
    assert run_cli(*SMALL, *long_budget[:1], *long_budget[1:]) == 0
    assert run.main(["--resume", str(run_dir), "--stop-after-minutes", "0"]) == 0
    config, _ = rundir.read_config(run_dir)
    assert config.total_env_steps == 10_000_000_000
    assert config.num_updates * config.env_steps_per_update >= 10_000_000_000
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 9))
    # The host counts env steps in Python ints: rows of a run far past int32 carry exact counts.
    far = next(runlog.metric_rows({"loss": np.zeros(1)}, 3_000_000, 1024, 0.0, 1.0))
    assert far["env_steps"] == 3_000_001 * 1024


def test_a_teacher_loads_from_a_finished_run_and_labels_a_students_rollouts(finished_run):
    config, _ = rundir.read_config(finished_run)
    trained = final_params(finished_run)
    teacher = learners.load_teacher(finished_run)
    obs = jax.random.normal(jax.random.PRNGKey(7), (16, 9))
    expected = learners.make_trainer(config).act(trained, obs)
    np.testing.assert_array_equal(teacher(obs), expected)
    np.testing.assert_array_equal(teacher({"image": jnp.zeros((16, 8, 8, 1), jnp.uint8), "privileged": obs}), expected)
    student = dataclasses.replace(config, teacher=str(finished_run), num_envs=16, rollout_length=4)
    trainer = learners.make_trainer(student)
    state = jax.jit(trainer.init)(jax.random.PRNGKey(0), student.hparams())
    _, metrics = jax.jit(trainer.update)(state, student.hparams())
    assert float(metrics.loss.imitation) > 0 and np.isfinite(float(metrics.loss.imitation))
    # A teacher of another env is refused in one line that names both sides.
    three_links = dataclasses.replace(student, env_kwargs=(("num_links", 3),))
    with pytest.raises(ValueError) as refused:
        learners.make_trainer(three_links)
    assert str(refused.value) == (
        f"teacher={finished_run} observes (9,) of arm2d but this run's env, arm2d, gives a teacher (13,)"
    )
