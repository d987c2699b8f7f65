"""Run directories that cannot collide, cannot start broken and never lose a user's files; resumes that extend a
run; Ctrl-C; evaluation during training. All on arm2d with budgets of a few seconds."""

import dataclasses
import json
import logging
import os
import pathlib
import re
import shutil
import signal
import threading
from concurrent.futures import ThreadPoolExecutor

import jax
import numpy as np
import pytest

from experiments import configs, run
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import apply_overrides
from jaxarm.runner import learners, loop, metrics_log, programs, provenance, rundir, signals
from tests.experiments.test_run import SMALL  # the same compiled chunk as there


def run_cli(*args):
    return run.main(["--config", "ppo_arm2d_fixed", *SMALL, *args])


def final_leaves(run_dir: pathlib.Path):
    config, _ = rundir.read_config(run_dir)
    return jax.tree.leaves(learners.restore_state(run_dir, learners.make_trainer(config), config))


def assert_same_learner(run_dir: pathlib.Path, other: pathlib.Path):
    for left, right in zip(final_leaves(run_dir), final_leaves(other), strict=True):
        np.testing.assert_array_equal(left, right)


def snapshot(directory: pathlib.Path) -> dict[str, bytes]:
    return {str(path.relative_to(directory)): path.read_bytes() for path in directory.rglob("*") if path.is_file()}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("runs") / "reference"
    assert run_cli("--out", str(run_dir)) == 0
    return run_dir


def test_runs_started_in_the_same_second_without_out_both_finish(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(rundir.time, "strftime", lambda _: "20260101-000000")
    assert run_cli() == 0
    assert run_cli() == 0
    made = sorted(path.name for path in (tmp_path / "runs").iterdir())
    assert made == ["ppo_arm2d_fixed-20260101-000000", "ppo_arm2d_fixed-20260101-000000-2"]
    for name in made:
        assert checkpoint.latest_step(tmp_path / "runs" / name / "checkpoints") == 24


def test_a_second_process_on_a_run_directory_is_refused_and_changes_nothing(reference, capsys):
    before = snapshot(reference)
    with rundir.locked(reference):  # another open file description: flock refuses it as it would another process
        before = snapshot(reference)
        assert run.main(["--resume", str(reference)]) == 2
        assert "in use by another process" in capsys.readouterr().err
        assert run_cli("--out", str(reference)) == 2
        assert snapshot(reference) == before


def test_a_directory_holding_a_run_is_refused_in_library_terms_and_the_cli_adds_its_command(reference, capsys):
    config, preset = rundir.read_config(reference)
    with pytest.raises(rundir.RunDirError) as refused:
        loop.train(config, reference, preset=preset)
    assert "already holds a run; resume it (resume=True) or use another run directory" in str(refused.value)
    assert "--" not in str(refused.value), "a library caller has no flags to pass"
    before = snapshot(reference)
    assert run_cli("--out", str(reference)) == 2
    assert f"continue with: python -m experiments.run --resume {reference}" in capsys.readouterr().err
    assert snapshot(reference) == before


def test_a_foreign_directory_is_refused_and_its_files_untouched(reference, tmp_path, capsys):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "metrics.jsonl").write_text("my own metrics\n")
    (foreign / "eval.json").write_text("{}")
    before = snapshot(foreign)
    assert run_cli("--out", str(foreign)) == 2, "files of a run's names but no config.json are not a run"
    assert "holds files but no run (eval.json, metrics.jsonl; no config.json)" in capsys.readouterr().err
    assert snapshot(foreign) == before and sorted(path.name for path in foreign.iterdir()) == sorted(before)

    with_notes = tmp_path / "annotated"
    shutil.copytree(reference, with_notes)
    (with_notes / "notes.txt").write_text("my notes")
    before = snapshot(with_notes)
    assert run.main(["--resume", str(with_notes)]) == 2
    assert "not part of a jaxarm run (notes.txt)" in capsys.readouterr().err
    assert snapshot(with_notes) == before


def test_nan_before_the_first_checkpoint_says_so_and_the_run_starts_again(reference, tmp_path):
    config, preset = rundir.read_config(reference)
    run_dir = tmp_path / "nan"
    # A reward scale this large makes the first value loss overflow to inf.
    diverging = dataclasses.replace(config, reward_scale=1e30)
    with pytest.raises(loop.TrainingDiverged) as raised:
        loop.train(diverging, run_dir, preset=preset)
    message = str(raised.value)
    assert "update 1 " in message and "before its first checkpoint" in message and "None" not in message
    assert (run_dir / "config.json").exists() and not rundir.any_checkpoint_files(run_dir)
    assert run_cli("--out", str(run_dir)) == 0, "re-running a run that never checkpointed starts it afresh"
    assert_same_learner(run_dir, reference)


def test_resume_of_a_run_that_died_before_its_first_checkpoint_starts_it(reference, tmp_path):
    run_dir = tmp_path / "died"
    run_dir.mkdir()
    shutil.copy(reference / "config.json", run_dir / "config.json")
    (run_dir / "metrics.jsonl").write_text('{"updates": 1, "wall_ti')  # killed while writing its first row
    assert run.main(["--resume", str(run_dir)]) == 0
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 25))
    assert_same_learner(run_dir, reference)


def test_damaged_files_are_named_with_what_to_do(reference, tmp_path, capsys):
    half_written = tmp_path / "half"
    shutil.copytree(reference, half_written)
    with (half_written / "metrics.jsonl").open("a") as log:
        log.write('{"updates": 25, "wall_t')
    assert run.main(["--resume", str(half_written)]) == 0, "a half-written last row is dropped on resume"
    assert [row["updates"] for row in metrics_log.read_metrics(half_written)] == list(range(1, 25))
    assert "has finished its 24 updates" in capsys.readouterr().err

    lines = (reference / "metrics.jsonl").read_text().splitlines()
    (half_written / "metrics.jsonl").write_text("\n".join([*lines[:2], "garbage", *lines[2:]]) + "\n")
    with pytest.raises(rundir.RunDirError, match=r"metrics.jsonl line 3 is not a JSON row .*delete that line"):
        metrics_log.read_metrics(half_written)

    (half_written / "config.json").write_text('{"preset": ')
    assert run.main(["--resume", str(half_written)]) == 2
    error = capsys.readouterr().err
    assert f"{half_written / 'config.json'} is corrupt" in error and "fix or restore" in error
    assert error.count("\n") == 1


def test_checkpoints_that_are_no_folder_stop_a_resume_without_deleting_anything(reference, tmp_path, capsys):
    # Taken for "no checkpoint", it restarted the run afresh and deleted its metrics.
    run_dir = tmp_path / "replaced"
    shutil.copytree(reference, run_dir)
    shutil.rmtree(run_dir / "checkpoints")
    (run_dir / "checkpoints").write_text("")
    rows = (run_dir / "metrics.jsonl").read_text()
    assert run.main(["--resume", str(run_dir)]) == 2
    error = capsys.readouterr().err
    assert f"{run_dir / 'checkpoints'} is not a folder" in error and error.count("\n") == 1, error
    assert (run_dir / "metrics.jsonl").read_text() == rows and (run_dir / "checkpoints").is_file()


def test_ctrl_c_checkpoints_at_the_chunk_end_and_resume_is_bit_identical(reference, tmp_path, capsys, monkeypatch):
    run_dir = tmp_path / "interrupted"
    runner_of = programs.ChunkRunners.__call__
    calls = []

    def interrupting_runner(runners, count):
        chunk = runner_of(runners, count)

        def run_chunk(state, hparams):
            calls.append(1)
            if len(calls) == 2:  # Ctrl-C while the second chunk runs
                os.kill(os.getpid(), signal.SIGINT)
            return chunk(state, hparams)

        return run_chunk

    monkeypatch.setattr(programs.ChunkRunners, "__call__", interrupting_runner)
    assert run_cli("checkpoint_every_updates=12", "--out", str(run_dir)) == 130
    error = capsys.readouterr().err
    assert "SIGINT: stopping at the next chunk end" in error
    assert f"continue with: python -m experiments.run --resume {run_dir}" in error
    assert checkpoint.latest_step(run_dir / "checkpoints") == 8, "checkpointed at the chunk end, off its cadence"
    assert signal.getsignal(signal.SIGINT) is signals.raise_and_remember, "the loop's handler is removed again"
    monkeypatch.undo()
    assert run.main(["--resume", str(run_dir)]) == 0
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 25))
    assert_same_learner(run_dir, reference)


def test_the_first_chunk_compiles_on_the_pool_while_the_start_state_is_made(tmp_path, monkeypatch):
    events, compiled_on = [], []
    make_runner, start, compile_lowered = programs.make_chunk_runner, loop._start, jax.stages.Lowered.compile

    def counted(trainer, count, *placement):
        events.append(count)
        return make_runner(trainer, count, *placement)

    def started(*args, **kwargs):
        events.append("start")
        return start(*args, **kwargs)

    def recorded(lowered, *args, **kwargs):
        compiled_on.append(threading.current_thread().name)
        return compile_lowered(lowered, *args, **kwargs)

    monkeypatch.setattr(programs, "make_chunk_runner", counted)
    monkeypatch.setattr(loop, "_start", started)
    monkeypatch.setattr(jax.stages.Lowered, "compile", recorded)
    # 2 updates, one chunk of 2; resumed, 22 more: chunks of 4 with one program made ahead, the last 2 at its call.
    assert run_cli("anneal_learning_rate=false", "total_env_steps=2048", "--out", str(tmp_path / "run")) == 0
    assert run.main(["--resume", str(tmp_path / "run"), "total_env_steps=24576"]) == 0
    assert events == [2, "start", 4, "start", 2], "the first chunk's program made before the start state"
    assert compiled_on == ["compile_0"] * 4, "each run's first chunk and its evaluation, on the pool"


def test_resume_extends_the_budget_as_if_it_had_been_set_at_the_start(tmp_path, capsys):
    constant = ["anneal_learning_rate=false", "--out"]
    assert run_cli(*constant, str(tmp_path / "short")) == 0
    assert run.main(["--resume", str(tmp_path / "short"), "total_env_steps=32768", "eval_episodes=10"]) == 0
    assert run_cli("total_env_steps=32768", "eval_episodes=10", *constant, str(tmp_path / "long")) == 0
    assert [row["updates"] for row in metrics_log.read_metrics(tmp_path / "short")] == list(range(1, 33))
    assert_same_learner(tmp_path / "short", tmp_path / "long")
    config, _ = rundir.read_config(tmp_path / "short")
    assert config.total_env_steps == 32768
    (record,) = [json.loads(line) for line in (tmp_path / "short" / "resumes.jsonl").read_text().splitlines()]
    assert record["overrides"] == ["total_env_steps=32768", "eval_episodes=10"] and record["resumed_at_update"] == 24
    assert [
        entry["event"] for entry in json.loads((tmp_path / "short" / "provenance.json").read_text())["records"]
    ] == [
        "start",
        "resume",
    ]


def test_a_run_records_its_provenance(reference):
    (entry,) = json.loads((reference / "provenance.json").read_text())["records"]
    assert entry["event"] == "start" and entry["hostname"] and entry["command"]
    assert entry["packages"]["jax"] == jax.__version__ and entry["packages"]["python"].startswith("3.")
    assert {"jaxlib", "mujoco", "mujoco-mjx", "flax", "optax", "orbax-checkpoint", "numpy", "warp-lang"} <= set(
        entry["packages"]
    )
    assert entry["devices"] and entry["devices"][0].startswith(jax.devices()[0].platform)
    assert len(entry["git"]["commit"]) == 40 and isinstance(entry["git"]["dirty"], bool), "tests run in a checkout"
    assert provenance.git_state(reference) == {"commit": None, "dirty": None}, "no checkout, no commit"


def test_resume_of_a_finished_run_says_so_and_changes_nothing(reference, capsys):
    before = snapshot(reference)
    assert run.main(["--resume", str(reference)]) == 0
    notice = capsys.readouterr().err
    assert "has finished its 24 updates; nothing done" in notice
    assert f"python -m experiments.eval {reference}" in notice, "the command that evaluates it again"
    assert snapshot(reference) == before, "no evaluation, no rewritten eval.json"


def test_resume_refuses_overrides_that_change_the_learner_and_changes_nothing(reference, capsys):
    before = snapshot(reference)
    assert run.main(["--resume", str(reference), "learning_rate=1e-2"]) == 2
    error = capsys.readouterr().err
    assert "cannot change 'learning_rate'" in error and "may change total_env_steps, checkpoint_every_updates" in error
    assert run.main(["--resume", str(reference), "total_env_steps=99999"]) == 2
    assert "learning-rate schedule (anneal_learning_rate=true)" in capsys.readouterr().err
    assert run.main(["--resume", str(reference), "=3"]) == 2  # was "cannot change ''"
    assert "error: override '=3' is not of the form key=value" in capsys.readouterr().err
    assert snapshot(reference) == before


def test_a_resume_that_cannot_restore_records_nothing(reference, tmp_path, capsys):
    damaged = tmp_path / "damaged"
    shutil.copytree(reference, damaged)
    for path in (damaged / "checkpoints").rglob("*"):
        if path.is_file():
            path.write_text("garbage")
    before = snapshot(damaged)
    assert run.main(["--resume", str(damaged), "eval_episodes=5"]) == 2
    error = capsys.readouterr().err
    assert "cannot be restored" in error and error.count("\n") == 1, "one line, orbax's own log lines silenced"
    assert snapshot(damaged) == before and not (damaged / "resumes.jsonl").exists()


def test_evaluation_during_training_logs_rows_keeps_the_best_and_draws_them(tmp_path, monkeypatch):
    made = []
    make_evaluator = learners.make_evaluator

    def counted(*args, **kwargs):
        made.append(args)
        return make_evaluator(*args, **kwargs)

    monkeypatch.setattr(learners, "make_evaluator", counted)
    run_dir = tmp_path / "evaluated"
    assert run_cli("eval_every_updates=8", "--out", str(run_dir)) == 0
    assert len(made) == 1, "one evaluation program for the evaluations during training and the final one"
    rows = metrics_log.read_metrics(run_dir)
    assert [row["updates"] for row in rows if "eval/success_rate" in row] == [8, 16, 24]
    best = json.loads((run_dir / "best.json").read_text())
    evaluated = [row for row in rows if "eval/success_rate" in row]
    top = max(evaluated, key=lambda row: (row["eval/success_rate"], row["eval/return_mean"]))
    assert best["updates"] == top["updates"] and best["success_rate"] == top["eval/success_rate"]
    assert checkpoint.latest_step(run_dir / "best") == best["updates"]
    final = json.loads((run_dir / "eval.json").read_text())
    assert final["success_rate"] == evaluated[-1]["eval/success_rate"], "same episodes as the final evaluation"


def test_an_evaluation_compiled_ahead_on_a_thread_gives_what_one_compiled_at_its_call(reference):
    config, state = loop.load_run(reference)
    trainer, key = learners.make_trainer(config), jax.random.PRNGKey(7)
    ahead, submitted = learners.make_evaluator(trainer, config, 8), []

    class Pool(ThreadPoolExecutor):
        def submit(self, *args, **kwargs):
            submitted.append(args)
            return super().submit(*args, **kwargs)

    with Pool(1) as pool:
        ahead.compile_ahead(pool, state, key)
        ahead.compile_ahead(pool, state, key)
    assert len(submitted) == 1, "compiled once"
    assert ahead(state, key) == learners.make_evaluator(trainer, config, 8)(state, key)


EVALUATION_KEY = re.compile(r"for 'jit_evaluate_policy' with key '([^']+)'")


def evaluation_cache_keys(caplog, run) -> set[str]:
    """The persistent-cache keys of the evaluation programs `run()` compiles or reads back (JAX logs each key).
    Set process-wide, not by JAX's context managers: the run compiles its evaluation on a thread of its own."""
    caplog.clear()
    flags = ("jax_log_compiles", "jax_explain_cache_misses")
    before = {flag: getattr(jax.config, flag) for flag in flags}
    try:
        for flag in flags:
            jax.config.update(flag, True)
        with caplog.at_level(logging.WARNING, "jax._src.compiler"):
            run()
    finally:
        for flag, value in before.items():
            jax.config.update(flag, value)
    return set(EVALUATION_KEY.findall(caplog.text))


@pytest.mark.skipif(not jax.config.jax_compilation_cache_dir, reason="needs the persistent compilation cache")
def test_the_eval_command_reads_back_the_evaluation_training_compiled(tmp_path, caplog):
    run_dir = tmp_path / "run"
    trained = evaluation_cache_keys(caplog, lambda: run_cli("--out", str(run_dir)))
    config, _ = rundir.read_config(run_dir)
    trainer = learners.make_trainer(config)
    state = learners.restore_state(run_dir, trainer, config, acting=True)
    evaluated = evaluation_cache_keys(
        caplog, lambda: learners.evaluate_state(trainer, config, state, config.eval_episodes, seed=3)
    )
    assert len(trained) == 1, trained
    assert evaluated == trained, "experiments.eval compiles its program again"


def test_lists_parse_with_brackets_too():
    base = configs.get("ppo_arm2d")
    for text in ("32,16", "[32,16]", "(32, 16)"):
        assert apply_overrides(base, [f"policy_hidden_sizes={text}"]).policy_hidden_sizes == (32, 16)


def test_a_budget_that_whole_chunks_overshoot_is_reported(tmp_path, capsys):
    # 1,024 env steps an update: 20,000 need 19.5 updates, run as 5 whole chunks of 4 (20,480 env steps).
    assert run_cli("total_env_steps=20000", "--out", str(tmp_path / "run")) == 0
    assert (
        "total_env_steps=20,000 runs as 20,480 env steps (+2%): 20 updates in whole chunks of 4"
        in capsys.readouterr().err
    )


def test_what_the_commands_write_beside_a_run_is_part_of_it(tmp_path):
    written = [
        "eval-1000-7-490.json",
        "robustness-200-777.md",
        "transfer-menagerie-200-12345.json",
        "transfer-jaxarm.gif",
        "rehearse-20-12345-24-20ms-stall-tick50.json",  # refused eval and resume of the rehearsed run before
    ]
    for name in [*written, "config.json", "notes.txt"]:
        (tmp_path / name).write_text("{}")
    assert rundir.foreign_files(tmp_path) == ["notes.txt"]


def test_damaged_side_files_are_named_in_one_line_and_kept(tmp_path):
    metrics = tmp_path / "metrics.jsonl"
    row = b'{"updates": 1, "env_steps": 8, "wall_time": 0.5}\n'
    for content, problem in [
        (bytes(range(256)), "line 1 is not a JSON row ("),
        (row + b"3\n", "line 2 is not a JSON row (a JSON int, not an object)"),
        (row + b'\xff\xfe{"updates": 2}\n', "line 2 is not a JSON row ("),
        (b'{"updates": "x", "env_steps": 8, "wall_time": 1}\n', "line 1 is not a JSON row (no updates of the right"),
        (b"{}\n", "line 1 is not a JSON row (no updates or env_steps or wall_time of the right type)"),
    ]:
        metrics.write_bytes(content)
        with pytest.raises(rundir.RunDirError) as raised:
            metrics_log.read_metrics(tmp_path)
        assert str(raised.value).startswith(f"{metrics} {problem}") and "\n" not in str(raised.value)
    provenance_path = tmp_path / rundir.PROVENANCE_FILE
    for content, problem in [
        ("{", "JSONDecodeError"),
        ("[]", "TypeError"),
        ('{"runs": []}', "KeyError: 'records'"),
        ('{"records": 5}', "TypeError: records is not a list"),
    ]:
        provenance_path.write_text(content)
        with pytest.raises(rundir.RunDirError) as raised:
            provenance.append_provenance(tmp_path, "resume")
        assert str(raised.value).startswith(f"{provenance_path} is corrupt or of another version ({problem}")
        assert provenance_path.read_text() == content, "a damaged history is never written over"
    config_path = tmp_path / "config.json"
    for content in ["null", "[1, 2]"]:  # null gave an AttributeError traceback, a list a TypeError about ints
        config_path.write_text(content)
        with pytest.raises(rundir.RunDirError) as raised:
            rundir.read_config(tmp_path, validate=False)
        kind = type(json.loads(content)).__name__
        assert str(raised.value).startswith(f"{config_path} is corrupt or of another version (TypeError: a JSON {kind}")


def test_robustness_tables_of_other_checkpoints_or_requests_never_replace_each_other(tmp_path):
    request = ["action_scale=0.1,0.002"]
    stem = rundir.robustness_stem(tmp_path, 200, 7, "24", request)
    assert stem.name.startswith("robustness-200-7-24-") and rundir.foreign_files(tmp_path) == []
    assert rundir.robustness_stem(tmp_path, 200, 7, "24", list(request)) == stem
    others = [
        rundir.robustness_stem(tmp_path, 200, 7, "best", request),
        rundir.robustness_stem(tmp_path, 200, 7, "24", ["goal_size=0.05"]),
        rundir.robustness_stem(tmp_path, 200, 7, "24", [*request, "--randomized-ends"]),
    ]
    assert len({stem, *others}) == 4
    for path in [stem, *others]:
        path.with_suffix(".json").write_text("{}")
    assert rundir.foreign_files(tmp_path) == []


def test_transfers_of_other_checkpoints_clipping_or_biases_never_replace_each_other(tmp_path):
    none = (0.0, 0.0, 0.0)
    stems = [
        rundir.transfer_stem(tmp_path, "jaxarm", 200, 7, "24", True, none),
        rundir.transfer_stem(tmp_path, "jaxarm", 200, 7, "24", False, none),
        rundir.transfer_stem(tmp_path, "jaxarm", 200, 7, "best", True, none),
        rundir.transfer_stem(tmp_path, "menagerie", 200, 7, "24", True, none),
        rundir.transfer_stem(tmp_path, "jaxarm", 200, 7, "24", True, (0.01, 0.0, 0.0)),
        rundir.transfer_stem(tmp_path, "jaxarm", 200, 7, "24", False, (-0.0005, 0.01, 0.0)),
    ]
    assert stems[0].name == "transfer-jaxarm-200-7-24" and stems[1].name == "transfer-jaxarm-200-7-24-noclip"
    assert stems[4].name == "transfer-jaxarm-200-7-24-bias10_0_0mm"
    assert stems[5].with_suffix(".json").name == "transfer-jaxarm-200-7-24-noclip-bias-0p5_10_0mm.json"
    assert len(set(stems)) == 6
    for stem in stems:
        for suffix in (".json", ".gif", ".mp4"):
            stem.with_suffix(suffix).write_text("")
    assert rundir.foreign_files(tmp_path) == []


def test_missing_metric_rows_are_named_by_their_spans(tmp_path):
    rows = [{"updates": update} for update in (1, 2, 5, 6, 9, 11, 13)]
    assert metrics_log.missing_metrics(tmp_path, rows[:2], 2) is None
    message = metrics_log.missing_metrics(tmp_path, rows, 14)
    assert message is not None and message.startswith(
        f"{tmp_path / 'metrics.jsonl'} lacks the rows of updates 3-4, 7-8, 10, ... (7 of the 14 the checkpoint"
    )
