"""Faults a user meets: a kill while the first checkpoint is written, a full disk, read-only places, bad paths,
parallel sweeps, edited configs, Ctrl-C at the edges. Each ends in one line naming what to do, and nothing is lost
or stuck. All on arm2d with budgets of a few seconds (the chunk compiled in test_run.py)."""

import csv
import dataclasses
import errno
import json
import os
import pathlib
import shutil
import signal
import struct
import subprocess
import sys
import textwrap
import time
import types

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp
import pytest
from jax.experimental import io_callback
from tensorboardX.proto import event_pb2

from experiments import compare, configs, export, run, start_up, sweep
from experiments import eval as eval_cli
from jaxarm.agents.common import checkpoint
from jaxarm.agents.common.config import apply_overrides
from jaxarm.exits import STOPPED_BY_SIGNAL
from jaxarm.runner import loop, metrics_log, paths, rundir, signals, sinks
from tests.experiments.test_run import SMALL
from tests.experiments.test_rundir import assert_same_learner, run_cli, snapshot

SWEEP = ["num_envs=64", "rollout_length=16", "num_minibatches=2", "total_env_steps=4096", "eval_episodes=4"]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """A finished run that evaluated during training, so it has a best checkpoint too."""
    run_dir = tmp_path_factory.mktemp("runs") / "reference"
    assert run_cli("eval_every_updates=8", "--out", str(run_dir)) == 0
    return run_dir


def error_lines(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]


def a_run_that_died_in_its_first_checkpoint(reference: pathlib.Path, run_dir: pathlib.Path) -> None:
    """What a kill (or a full disk) during the first save leaves: config.json and orbax's temporary folder."""
    run_dir.mkdir()
    shutil.copy(reference / "config.json", run_dir / "config.json")
    unfinished = run_dir / "checkpoints" / f"4{checkpoint.TEMPORARY_SUFFIX}-1764000000"
    unfinished.mkdir(parents=True)
    (unfinished / "_CHECKPOINT_METADATA").write_text("{")
    (run_dir / "metrics.jsonl").write_text('{"updates": 1}\n')


@pytest.mark.parametrize("again", ["--resume", "--out"])
def test_a_kill_during_the_first_checkpoint_restarts_the_run_saying_so(reference, tmp_path, capsys, again):
    run_dir = tmp_path / "died"
    a_run_that_died_in_its_first_checkpoint(reference, run_dir)
    if again == "--resume":
        assert run.main(["--resume", str(run_dir)]) == 0
    else:
        assert run_cli("eval_every_updates=8", "--out", str(run_dir)) == 0
    assert "no complete checkpoint (only a half-written one, 4.orbax-checkpoint-tmp" in capsys.readouterr().err
    assert checkpoint.half_written(run_dir / "checkpoints") == []
    assert_same_learner(run_dir, reference)


def test_a_full_disk_at_a_later_checkpoint_is_one_line_and_the_run_resumes(reference, tmp_path, capsys, monkeypatch):
    run_dir = tmp_path / "full"
    save = ocp.CheckpointManager.save

    def save_until_the_disk_fills(manager, step, *args, **kwargs):
        if step == 8 and pathlib.Path(manager.directory).name == "checkpoints":
            (pathlib.Path(manager.directory) / f"8{checkpoint.TEMPORARY_SUFFIX}-1").mkdir()
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return save(manager, step, *args, **kwargs)

    def close_on_a_full_disk(sink):
        sink.writer.close()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(ocp.CheckpointManager, "save", save_until_the_disk_fills)
    monkeypatch.setattr(sinks.TensorBoardSink, "close", close_on_a_full_disk)
    assert run_cli("eval_every_updates=8", "--out", str(run_dir)) == 2
    (line,) = error_lines(capsys)
    assert f"cannot write checkpoint 8 in {run_dir / 'checkpoints'}: No space left on device" in line
    assert f"continue with: python -m experiments.run --resume {run_dir}" in line
    assert checkpoint.latest_step(run_dir / "checkpoints") == 4
    monkeypatch.undo()
    assert run.main(["--resume", str(run_dir)]) == 0, "space freed: the run goes on from checkpoint 4"
    assert checkpoint.half_written(run_dir / "checkpoints") == []
    assert [row["updates"] for row in metrics_log.read_metrics(run_dir)] == list(range(1, 25))
    assert_same_learner(run_dir, reference)


def failed_program() -> jax.errors.JaxRuntimeError:
    """The error JAX raises for a compiled program whose host callback raised, as an env's host check does."""

    def check(_) -> None:
        raise RuntimeError("probe fault in 8 envs")

    try:
        jax.block_until_ready(jax.jit(lambda x: io_callback(check, None, x, ordered=True))(jnp.ones(())))
    except jax.errors.JaxRuntimeError as error:
        return error
    raise AssertionError("the program ran")


def test_a_program_that_fails_on_the_device_ends_in_a_line_that_says_what_is_kept(
    reference, tmp_path, capsys, monkeypatch
):
    # A Warp launch failed so in the fifth chunk of a sorter run (H200, 2026-11-29): ~100 lines of tracebacks,
    # nothing to say that the run resumes. The traceback stays, for a report; the last line says what to do.
    run_dir, flatten, chunks_done = tmp_path / "failed", metrics_log.flatten_metrics, []

    def fail_in_the_second_chunk(metrics, *prefix):  # called again for the metrics' parts, with a prefix
        chunks_done.extend([] if prefix else [1])
        if len(chunks_done) == 2:
            raise failed_program()
        return flatten(metrics, *prefix)

    monkeypatch.setattr(metrics_log, "flatten_metrics", fail_in_the_second_chunk)
    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)  # put back after the test
    assert run_cli("eval_every_updates=8", "--out", str(run_dir)) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err
    assert err.strip().splitlines()[-1] == (
        "error: training failed on the device: RuntimeError: probe fault in 8 envs; checkpoints saved so far are "
        f"kept; continue with: python -m experiments.run --resume {run_dir}"
    )
    assert checkpoint.latest_step(run_dir / "checkpoints") == 4
    monkeypatch.setattr(metrics_log, "flatten_metrics", flatten)
    assert run.main(["--resume", str(run_dir)]) == 0
    assert_same_learner(run_dir, reference)


def test_a_device_error_said_is_not_printed_again_at_exit(monkeypatch):
    # JAX's exit handlers wait on the failed program's effects and raise its error again (Warp, H200).
    heard = []
    monkeypatch.setattr(sys, "unraisablehook", heard.append)
    said = failed_program()
    run.said_once(said)
    for error in (failed_program(), RuntimeError("another")):
        sys.unraisablehook(types.SimpleNamespace(exc_value=error))
    assert [str(each.exc_value) for each in heard] == ["another"]


FILES_LIMITED = textwrap.dedent("""
    import importlib, resource, signal, sys

    # Each file written past the limit fails with EFBIG, from the OS inside orbax's and tensorstore's own writing
    # threads, as a full disk fails them (a small tmpfs would need privileges CI has not).
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # else the kernel kills the writer
    resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[1]), int(sys.argv[1])))
    sys.exit(importlib.import_module(f"experiments.{sys.argv[2]}").main(sys.argv[3:]))
""")
"""`python -c FILES_LIMITED SIZE COMMAND ARGS...`: `python -m experiments.COMMAND ARGS...` with files limited to SIZE
bytes."""


def test_a_real_write_failure_at_the_first_checkpoint_is_one_line_and_the_run_starts_again(reference, tmp_path):
    run_dir = tmp_path / "run"
    failed = subprocess.run(
        [sys.executable, "-c", FILES_LIMITED, "20000", "run", "--config", "ppo_arm2d_fixed", *SMALL]
        + ["eval_every_updates=8", "--out", str(run_dir)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    # Orbax closed its event loop at the first failed write, and the writes in flight each reported that closed
    # loop as a traceback (up to 190 of them; also on a real full disk, 7 of 12 tries on a 300 KB tmpfs).
    assert [line for line in failed.stderr.splitlines() if not line.startswith("env steps")] == [
        f"error: cannot write checkpoint 4 in {run_dir / 'checkpoints'}: File too large (checkpoints saved before "
        f"are intact); fix that, then resume the run to continue; continue with: python -m experiments.run "
        f"--resume {run_dir}"
    ]
    assert failed.returncode == 2 and checkpoint.latest_step(run_dir / "checkpoints") is None
    assert run.main(["--resume", str(run_dir)]) == 0, "the run starts again from its config"
    assert_same_learner(run_dir, reference)


def refuse_writes_under(monkeypatch, read_only: pathlib.Path) -> None:
    """Writes under `read_only` fail as on a read-only mount (chmod would not stop root, who runs CI)."""
    mkdir, open_ = pathlib.Path.mkdir, pathlib.Path.open

    def refused(path: pathlib.Path) -> bool:
        return path == read_only or read_only in path.parents

    def guarded_mkdir(path, *args, **kwargs):
        if refused(path):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return mkdir(path, *args, **kwargs)

    def guarded_open(path, mode="r", *args, **kwargs):
        if refused(path) and any(flag in mode for flag in "wax+"):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return open_(path, mode, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "mkdir", guarded_mkdir)
    monkeypatch.setattr(pathlib.Path, "open", guarded_open)


def test_read_only_targets_get_one_line_naming_the_path(reference, tmp_path, capsys, monkeypatch):
    read_only = tmp_path / "mounted"
    read_only.mkdir()
    copy = read_only / "run"
    shutil.copytree(reference, copy)
    before = snapshot(copy)
    refuse_writes_under(monkeypatch, read_only)
    for code, argv in [
        (run.main, ["--config", "ppo_arm2d_fixed", "--out", str(read_only / "new")]),
        (run.main, ["--resume", str(copy)]),
        (export.main, [str(reference), "--out", str(read_only / "export")]),
        (export.main, [str(copy)]),
    ]:
        assert code(argv) == 2, argv
        (line,) = error_lines(capsys)
        assert str(read_only) in line and ("read-only" in line.lower() or "not writable" in line), line
    assert snapshot(copy) == before


@pytest.mark.parametrize("tool", ["run", "sweep", "export", "compare"])
def test_bad_out_paths_are_refused_in_one_line_or_made(reference, tmp_path, capsys, tool):
    a_file = tmp_path / "notes.md"
    a_file.write_text("mine")
    entry = {
        "run": lambda out: run_cli("--out", out),
        "sweep": lambda out: sweep.main(["--config", "ppo_arm2d_fixed", "--seeds", "1", *SWEEP, "--out", out]),
        "export": lambda out: export.main([str(reference), "--out", out]),
        "compare": lambda out: compare.main([str(reference), "--out", out]),
    }[tool]
    bad = [(a_file, "is a file" if tool != "compare" else "name one of"), (a_file / "out", "which is a file")]
    if tool != "compare":
        bad.append((tmp_path / "results.txt", "the name of a .txt file"))
        # A name of bytes that are not UTF-8 (as `--out $'x\\xff'` gives): a run failed at its first checkpoint.
        bad.append((tmp_path / os.fsdecode(b"x\xff"), "is not a UTF-8 name"))
    else:
        bad.append((tmp_path / "results.txt", "name one of"))
    for out, message in bad:
        assert entry(str(out)) == 2, out
        (line,) = error_lines(capsys)
        assert os.fsencode(out).decode(errors="backslashreplace") in line and message in line, line
    assert a_file.read_text() == "mine" and not (tmp_path / "results.txt").exists()
    with pytest.raises(SystemExit) as exited:  # `--out "$DIR"` of an unset DIR: the default place, without a word
        entry("")
    assert exited.value.code == 2 and "argument --out: expected a path, got an empty one" in capsys.readouterr().err
    if tool in ("export", "compare"):  # quick ones: missing parents are made, and the message says what was written
        assert entry(str(tmp_path / "new" / "deeper")) == 0
        written = tmp_path / "new" / ("deeper.png" if tool == "compare" else "deeper/policy.npz")
        assert f"wrote {written}" in capsys.readouterr().out


def test_compare_into_a_directory_says_what_it_wrote(reference, tmp_path, capsys):
    assert compare.main([str(reference), "--out", str(tmp_path)]) == 0
    assert f"wrote {tmp_path / 'compare.png'}" in capsys.readouterr().out
    assert (tmp_path / "compare.png").stat().st_size > 1000
    assert compare.main([str(reference), "--out", str(tmp_path / "figure")]) == 0
    assert f"wrote {tmp_path / 'figure.png'}" in capsys.readouterr().out


def test_a_sweep_never_replaces_another_sweeps_results(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["--config", "ppo_arm2d_fixed", "--seeds", "1", *SWEEP, "--out", str(out)]
    with rundir.locked(out, check=rundir.check_empty):  # a sweep running there (flock refuses a second holder)
        assert sweep.main(argv) == 2
        assert "in use by another process" in capsys.readouterr().err
    assert not out.exists(), "the refused sweep left nothing behind"
    assert sweep.main(argv) == 0
    before = snapshot(out)
    assert [name for name in sorted(before) if "/" not in name] == [
        ".lock",
        "curves.png",
        "provenance.json",
        "results.csv",
        "results.md",
        "sweep.json",
    ]
    assert sweep.main(argv) == 2
    (line,) = error_lines(capsys)
    assert f"{out} already holds curves.png, group-0, provenance.json, results.csv, results.md, ...; choose" in line
    assert snapshot(out) == before
    assert sweep.main(["--resume", str(out)]) == 2
    assert f"the sweep in {out} has finished" in error_lines(capsys)[0]
    assert snapshot(out) == before


def result_rows(out: pathlib.Path) -> list[dict]:
    """A sweep's results.csv without its wall-clock column."""
    with (out / "results.csv").open() as handle:
        return [{key: value for key, value in row.items() if key != "group_wall_s"} for row in csv.DictReader(handle)]


def test_a_sweep_stopped_twice_and_resumed_computes_what_an_uninterrupted_one_does(tmp_path, capsys):
    # Two static groups (num_minibatches) of 2 learning rates x 2 seeds, 2 chunks each: the first stop falls inside
    # group 0, the second inside group 1, after group 0 was finished and kept.
    grid = ["--seeds", "2", *SWEEP, "updates_per_chunk=2", "num_minibatches=1,2", "learning_rate=0.001,0.003"]
    straight, stopped = tmp_path / "straight", tmp_path / "stopped"
    assert sweep.main(["--config", "ppo_arm2d_fixed", *grid, "--out", str(straight)]) == 0
    assert sweep.main(["--config", "ppo_arm2d_fixed", *grid, "--out", str(stopped), "--stop-after-minutes", "0"]) == 0
    assert "stopped after chunk 1/" in capsys.readouterr().out and not (stopped / "results.csv").exists()
    assert sweep.main(["--resume", str(stopped), "--stop-after-minutes", "0"]) == 0
    out = capsys.readouterr().out
    assert "resumed after chunk 1/" in out and "stopped after chunk 1/" in out
    assert (stopped / "group-0" / "group.json").exists() and not (stopped / "results.csv").exists()
    assert not (stopped / "group-0" / "checkpoints").exists(), "a finished group keeps its results, not its state"
    assert sweep.main(["--resume", str(stopped)]) == 0
    assert result_rows(stopped) == result_rows(straight)


def interrupted_sweep(out: pathlib.Path, signals: int) -> subprocess.CompletedProcess:
    """`experiments.sweep` of one group of 2 chunks into `out`, sent `signals` SIGINTs (0.5 s apart) once it names
    its group, while its first chunk compiles."""
    command = [sys.executable, "-u", "-m", "experiments.sweep", "--config", "ppo_arm2d_fixed", "--seeds", "2"]
    child = subprocess.Popen(
        [*command, *SWEEP, "updates_per_chunk=2", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None
    lines = []
    for line in child.stdout:
        lines.append(line)
        if line.startswith("group"):
            for index in range(signals):
                time.sleep(0.5 * index)
                child.send_signal(signal.SIGINT)
            break
    rest, err = child.communicate(timeout=300)
    return subprocess.CompletedProcess(child.args, child.returncode, "".join(lines) + rest, err)


@pytest.mark.slow
def test_ctrl_c_during_a_sweep_checkpoints_its_group_and_says_how_to_resume_in_one_line(tmp_path, capsys):
    once, twice = tmp_path / "once", tmp_path / "twice"
    resume = "; continue with: python -m experiments.sweep --resume "
    stopped = interrupted_sweep(once, 1)
    assert stopped.returncode == 130 and "Traceback" not in stopped.stderr, stopped.stderr[-3000:]
    assert stopped.stderr.strip().splitlines()[-1] == (
        f"interrupted: stopped after chunk 1/2 of a group, checkpointed in {once / 'group-0' / 'checkpoints'}"
        f"{resume}{once}"
    )
    aborted = interrupted_sweep(twice, 2)
    assert aborted.returncode == 130 and "Traceback" not in aborted.stderr, aborted.stderr[-3000:]
    assert aborted.stderr.strip().splitlines()[-1] == (
        f"SIGINT again: aborted; the checkpoints saved before are kept{resume}{twice}"
    )
    assert sweep.main(["--resume", str(once)]) == 0
    assert "resumed after chunk 1/2" in capsys.readouterr().out and (once / "results.csv").exists()


def test_a_real_write_failure_at_a_sweeps_checkpoint_is_one_line_and_the_sweep_resumes(tmp_path):
    out = tmp_path / "sweep"
    argv = ["--config", "ppo_arm2d_fixed", "--seeds", "2", *SWEEP, "updates_per_chunk=2", "--out", str(out)]
    failed = subprocess.run(
        [sys.executable, "-c", FILES_LIMITED, "20000", "sweep", *argv, "--stop-after-minutes", "0"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert failed.returncode == 2, failed.stderr[-3000:]
    (line,) = failed.stderr.strip().splitlines()
    saves = out / "group-0" / "checkpoints"
    assert line.startswith(f"error: cannot write checkpoint 1 in {saves}: File too large"), line
    assert line.endswith(f"; continue with: python -m experiments.sweep --resume {out}"), line
    assert sweep.main(["--resume", str(out)]) == 0, "space freed: the sweep goes on"
    assert (out / "results.csv").exists() and checkpoint.half_written(saves) == []


def test_a_real_write_failure_at_a_sweeps_figure_is_one_line_and_the_resume_makes_it(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["--config", "ppo_arm2d_fixed", "--seeds", "1", *SWEEP, "--out", str(out)]
    failed = subprocess.run(
        [sys.executable, "-c", FILES_LIMITED, "20000", "sweep", *argv], capture_output=True, text=True, timeout=300
    )
    assert failed.returncode == 2, failed.stderr[-3000:]
    line = failed.stderr.strip().splitlines()[-1]
    assert (
        line
        == f"error: {out / 'curves.png'}: File too large; continue with: python -m experiments.sweep --resume {out}"
    )
    assert sweep.main(["--resume", str(out)]) == 0, "space freed: the finished groups make the tables and figure"
    assert (out / "curves.png").stat().st_size > 1000 and (out / sweep.RESULTS_FILE).exists()
    assert sweep.main(["--resume", str(out)]) == 2 and "has finished" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("name", "content"),
    [
        (sweep.GROUP_FILE, b"{"),
        (sweep.GROUP_FILE, b"null"),  # a TypeError traceback on --resume
        (sweep.GROUP_FILE, b'{"rows": 3}'),  # a KeyError traceback
        (sweep.GROUP_FILE, b'{"rows": [], "labels": ["x"]}'),  # the group's rows left out, rc 0
        (sweep.CURVES_FILE, b"garbage"),
        (sweep.CURVES_FILE, b"PK\x03\x04 cut short"),
    ],
)
def test_a_finished_groups_damaged_files_are_named_in_one_line(tmp_path, name, content):
    folder = tmp_path / "group-0"
    curve = (np.arange(3.0), np.zeros(3), np.ones(3))
    sweep.write_group(folder, [{"setting": "a"}, {"setting": "b"}], {"a": curve, "b": curve})
    assert sweep.read_group(folder) is not None
    (folder / name).write_bytes(content)
    with pytest.raises(ValueError) as raised:
        sweep.read_group(folder)
    message = str(raised.value)
    assert message.startswith(f"{folder}, a finished group, is damaged or edited (") and "\n" not in message
    assert message.endswith("; delete it to train that group again")


def test_eval_of_the_best_and_of_the_latest_checkpoint_write_different_files(reference, capsys):
    assert eval_cli.main([str(reference), "--episodes", "4"]) == 0
    assert eval_cli.main([str(reference), "--episodes", "4", "--best"]) == 0
    latest = json.loads((reference / "eval-4-12345-24.json").read_text())
    best = json.loads((reference / "eval-4-12345-best.json").read_text())
    assert (
        latest["checkpoint_update"] == 24
        and best["checkpoint_update"] == json.loads((reference / "best.json").read_text())["updates"]
    )


def test_an_edited_config_is_held_to_what_a_resume_may_change(reference, tmp_path, capsys):
    edited = tmp_path / "edited"
    shutil.copytree(reference, edited)
    config = json.loads((edited / "config.json").read_text())
    (edited / "config.json").write_text(json.dumps({**config, "learning_rate": 0.01}))
    before = snapshot(edited)
    assert run.main(["--resume", str(edited)]) == 2
    (line,) = error_lines(capsys)
    assert f"editing {edited / 'config.json'} (learning_rate was {config['learning_rate']!r} at the checkpoint)" in line
    assert "cannot change 'learning_rate'" in line and "may change total_env_steps" in line
    assert snapshot(edited) == before
    (edited / "config.json").write_text(json.dumps({**config, "eval_episodes": 7}))
    assert run.main(["--resume", str(edited)]) == 0, "what the CLI may change, an edit may change too"


def test_an_edit_that_cannot_be_checked_is_said_in_one_line(reference, tmp_path, capsys):
    edited = tmp_path / "edited"
    shutil.copytree(reference, edited)
    (edited / "checkpoints" / "config.json").unlink()
    config = json.loads((edited / "config.json").read_text())
    (edited / "config.json").write_text(json.dumps({**config, "learning_rate": 0.01}))
    assert run.main(["--resume", str(edited)]) == 0
    (line,) = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert line == (
        f"warning: {edited / 'checkpoints' / 'config.json'}, the config of the latest checkpoint, is missing: an "
        f"edit of {edited / 'config.json'} since then cannot be checked; resuming with config.json as it is"
    )


@pytest.mark.parametrize("kept", [10, 0, None])
def test_metrics_cut_short_or_deleted_are_named_on_resume_and_the_rows_left_are_kept(reference, tmp_path, capsys, kept):
    cut = tmp_path / "cut"
    shutil.copytree(reference, cut)
    rows = metrics_log.read_metrics(cut)
    if kept is None:
        (cut / "metrics.jsonl").unlink()
    else:
        (cut / "metrics.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows[:kept]))
    # A resume that trains on (here: none left to do, then the final evaluation) goes from the checkpoint.
    assert run.main(["--resume", str(cut), "eval_episodes=4"]) == 0
    (line,) = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    missing = 24 - (kept or 0)
    assert line.startswith(f"warning: {cut / 'metrics.jsonl'} lacks the rows of updates {25 - missing}-24 ")
    assert f"({missing} of the 24 the checkpoint has done: cut short, deleted or edited); resuming" in line
    assert metrics_log.read_metrics(cut) == rows[: kept or 0], "the rows left are kept as they were"


@pytest.mark.parametrize("content", ["null", "{", '{"updates": 8}'])
def test_a_damaged_best_json_is_named_in_one_line_before_the_resume_writes(reference, tmp_path, capsys, content):
    damaged = tmp_path / "damaged"
    shutil.copytree(reference, damaged)
    (damaged / "best.json").write_text(content)  # null was taken for no best: a worse state replaced best/
    before = snapshot(damaged)
    assert run.main(["--resume", str(damaged), "eval_episodes=4"]) == 2
    (line,) = error_lines(capsys)
    assert line.startswith(f"error: {damaged / 'best.json'} is corrupt or of another version (")
    assert snapshot(damaged) == before


def test_a_budget_below_the_work_done_is_refused(reference):
    config, preset = rundir.read_config(reference)
    # What `--resume RUN total_env_steps=4096` asks of a run whose budget may change (no annealed schedule).
    smaller = dataclasses.replace(config, total_env_steps=4096)
    before = snapshot(reference)
    with pytest.raises(rundir.RunDirError, match="total_env_steps=4,096 is below the 24,576 env steps this run"):
        loop.train(smaller, reference, preset=preset, resume=True)
    assert snapshot(reference) == before


def test_a_finished_runs_eval_json_edited_to_another_shape_is_evaluated_again(reference):
    config, _ = rundir.read_config(reference, validate=False)
    assert rundir.finished_evaluation(reference, config) is not None
    edited = reference / "eval.json"
    kept = edited.read_text()
    try:
        for content in ["null", "[1]"]:  # null gave an AttributeError traceback on --resume
            edited.write_text(content)
            assert rundir.finished_evaluation(reference, config) is None
    finally:
        edited.write_text(kept)


def test_show_with_resume_shows_the_overrides(reference, capsys):
    assert run.main(["--resume", str(reference), "--show", "eval_episodes=7"]) == 0
    assert "eval_episodes (int, in [1, 1048576]) = 7" in capsys.readouterr().out
    assert run.main(["--resume", str(reference), "--show", "learning_rate=1"]) == 2
    assert "cannot change 'learning_rate'" in capsys.readouterr().err


@pytest.mark.parametrize("minutes", ["nan", "-1", "inf", "soon"])
def test_stop_after_minutes_must_be_a_finite_number_of_minutes(minutes, capsys):
    with pytest.raises(SystemExit) as exited:
        run.main(["--config", "ppo_arm2d_fixed", "--stop-after-minutes", minutes])
    assert exited.value.code == 2
    assert "expected a finite number of minutes, 0 or more" in capsys.readouterr().err


def tensorboard_steps(directory: pathlib.Path, tag: str) -> list[int]:
    """The steps TensorBoard shows for `tag`: events in file order, a restart (SessionLog START at step s)
    hiding the events before it at step s and beyond."""
    steps: list[int] = []
    for path in sorted(directory.iterdir()):
        data, offset = path.read_bytes(), 0
        while offset < len(data):
            (length,) = struct.unpack("<Q", data[offset : offset + 8])
            event = event_pb2.Event.FromString(data[offset + 12 : offset + 12 + length])
            offset += 12 + length + 4
            if event.HasField("session_log") and event.session_log.status == event_pb2.SessionLog.START:
                steps = [step for step in steps if step < event.step]
            elif event.HasField("summary") and any(value.tag == tag for value in event.summary.value):
                steps.append(event.step)
    return steps


def test_tensorboard_shows_each_step_once_after_a_kill_and_resume(tmp_path):
    run_dir = tmp_path / "killed"

    def die_after_update_12(updates):
        if updates == 12:  # logged 9-12, checkpointed only at 8: what a SIGKILL leaves
            raise SystemExit("killed")

    config = apply_overrides(configs.get("ppo_arm2d_fixed"), [*SMALL, "checkpoint_every_updates=8"])
    with pytest.raises(SystemExit):
        loop.train(config, run_dir, preset="ppo_arm2d_fixed", options=loop.Options(on_chunk=die_after_update_12))
    assert checkpoint.latest_step(run_dir / "checkpoints") == 8
    assert len(tensorboard_steps(run_dir / "tensorboard", "episodes/return_mean")) == 12
    assert run.main(["--resume", str(run_dir)]) == 0
    steps = tensorboard_steps(run_dir / "tensorboard", "episodes/return_mean")
    assert steps == [row["env_steps"] for row in metrics_log.read_metrics(run_dir)] and len(steps) == 24


def test_a_resume_in_the_same_second_keeps_the_events_of_the_writer_before_it(tmp_path, monkeypatch):
    from tensorboardX import event_file_writer

    # tensorboardX names its files by the second: one second for both writers, as a kill and a quick resume get.
    monkeypatch.setattr(event_file_writer, "time", types.SimpleNamespace(time=lambda: 1764412345.5))
    directory = tmp_path / "tensorboard"
    for first, last, purge_step in [(1, 12, None), (9, 24, 9)]:
        sink = sinks.TensorBoardSink(directory, purge_step=purge_step)
        for step in range(first, last + 1):
            sink.write({"env_steps": float(step), "episodes/return_mean": 0.0})
        sink.close()
    assert tensorboard_steps(directory, "episodes/return_mean") == list(range(1, 25))


def test_a_second_ctrl_c_ends_the_process_at_once_with_130():
    program = (
        "import os, signal, time\n"
        "from jaxarm.runner.signals import StopRequests\n"
        "with StopRequests().installed():\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(30)\n"
    )
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=120)
    assert done.returncode == 130 and "SIGINT again: aborted" in done.stderr


@pytest.mark.parametrize("nohup", [False, True])
def test_a_hang_up_stops_training_at_the_chunk_end_unheard_unless_the_run_ignores_it(nohup):
    # A closed terminal's SIGHUP ended a run at once (rc 129), losing the chunk in progress; under `nohup` it must
    # still be ignored. The test's pipes stand for the terminal: nothing written after the hang-up reaches them.
    program = (
        "import os, signal, sys\n"
        "from jaxarm.runner.signals import StopRequests\n"
        f"signal.signal(signal.SIGHUP, {'signal.SIG_IGN' if nohup else 'signal.SIG_DFL'})\n"
        "stop = StopRequests()\n"
        "with stop.installed():\n"
        "    print('before', flush=True)\n"
        "    os.kill(os.getpid(), signal.SIGHUP)\n"
        "    print('after', flush=True)\n"
        "    print('after', file=sys.stderr, flush=True)\n"
        "sys.exit(7 if stop.requested else 8)\n"
    )
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=120)
    if nohup:
        assert (done.returncode, done.stdout, done.stderr) == (8, "before\nafter\n", "after\n")
    else:
        assert (done.returncode, done.stdout, done.stderr) == (7, "before\n", "")


def test_a_ctrl_c_swallowed_before_training_stops_the_run_at_its_first_chunk_end(tmp_path):
    # A KeyboardInterrupt raised while XLA compiled was swallowed by JAX's garbage-collection callback: the run
    # trained to its end, rc 0. What the handler remembered stops the chunk loop at its first chunk end instead.
    with pytest.raises(KeyboardInterrupt):
        signals.raise_and_remember(signal.SIGINT, None)  # the exception a library then swallows
    config = apply_overrides(configs.get("ppo_arm2d_fixed"), [*SMALL, "updates_per_chunk=2"])
    with pytest.raises(loop.TrainingInterrupted, match="checkpoint at update 2 of"):
        loop.train(config, tmp_path / "r", preset="ppo_arm2d_fixed")
    assert checkpoint.latest_step(tmp_path / "r" / "checkpoints") == 2
    assert not signals.StopRequests().requested  # remembered once


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])  # SIGTERM ended it without a word (rc -15)
def test_ctrl_c_or_sigterm_during_start_up_imports_ends_the_run_at_once(tmp_path, signum):
    command = [sys.executable, "-m", "experiments.run", "--config", "ppo_arm2d_fixed", "--out", str(tmp_path / "r")]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
    # Inside the imports: a fixed 1.5 s wait landed after them on one CI run, the imports taking 1-6 s on a 2-core CPU.
    signal_once_jax_loads(process, signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == STOPPED_BY_SIGNAL == 130 and "interrupted while starting: nothing was written" in err
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("run_as_module", [True, False])
def test_the_package_takes_ctrl_c_over_first_where_python_locates_a_command_in_it(run_as_module):
    # Python sets sys.argv[0] to "-m" while it locates `python -m experiments.X`, which imports the package first.
    # From the entry module's first line, tracebacks came up to ~8 ms later, ~2-5 ms of them in our own imports.
    program = (
        "import signal, sys\n"
        f"sys.argv[0] = {'-m' if run_as_module else 'x.py'!r}\n"
        "import experiments\n"
        "from experiments import start_up\n"
        "print(signal.getsignal(signal.SIGINT) is start_up._exit_at_once, flush=True)\n"
        "start_up.exit_on_ctrl_c(start_up.AT_ONCE)\n"
        "start_up.start_up_over()\n"
        "print(signal.getsignal(signal.SIGTERM) is signal.SIG_DFL, flush=True)\n"
        "start_up.exit_on_ctrl_c(start_up.AT_ONCE)\n"
        "signal.raise_signal(signal.SIGINT)\n"
    )
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=120)
    assert done.stdout.split() == [str(run_as_module), "True"]
    assert done.returncode == 130 and done.stderr == f"\ninterrupted {start_up.AT_ONCE}\n", done.stderr


@pytest.mark.parametrize("command", [["experiments.run", "--list"], ["experiments.prepare", "--config", "ppo_arm2d"]])
def test_a_command_whose_reader_went_away_ends_quietly_as_a_closed_pipe_ends_others(command):
    # What `python -m experiments.run --list | head -1` meets once head has gone: a BrokenPipeError traceback before.
    read, write = os.pipe()
    os.close(read)
    with os.fdopen(write, "w") as gone:
        done = subprocess.run([sys.executable, "-m", *command], stdout=gone, stderr=subprocess.PIPE, text=True)
    assert done.returncode == 128 + signal.SIGPIPE == 141 and done.stderr == "", done.stderr


def signal_once_jax_loads(process: subprocess.Popen, signum: int) -> None:
    """Sends `signum` to `process` once jaxlib's library is mapped in it: amid the imports that follow (mujoco,
    flax, the presets), where a KeyboardInterrupt could be swallowed or end in a traceback."""
    maps = pathlib.Path(f"/proc/{process.pid}/maps")
    deadline = time.monotonic() + (60 if maps.exists() else 1.5)  # without /proc (macOS): a wait
    while time.monotonic() < deadline and not (maps.exists() and "jaxlib" in maps.read_text()):
        time.sleep(0.005)
    process.send_signal(signum)


@pytest.mark.parametrize("command", ["eval", "export", "compare"])
def test_ctrl_c_ends_a_command_that_trains_nothing_at_once_in_one_line(reference, tmp_path, command):
    # A KeyboardInterrupt there ended in tracebacks of up to 158 lines, or was swallowed (an evaluation ran on, rc 0).
    out = {"eval": [], "export": ["--out", str(tmp_path / "export")], "compare": ["--out", str(tmp_path / "c.png")]}
    argv = [sys.executable, "-m", f"experiments.{command}", str(reference), *out[command]]
    process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    signal_once_jax_loads(process, signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == STOPPED_BY_SIGNAL
    assert err == "\ninterrupted and ended at once; run the command again for its results\n", err[-3000:]
    assert list(tmp_path.iterdir()) == []


def test_os_errors_name_the_path_or_the_directory_written_to():
    full = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # a write to an open file names no path
    assert paths.os_error_message(full, "runs/a") == (
        "writing into runs/a: No space left on device; the disk is full; free space and retry (a resumed run goes on)"
    )
    read_only = OSError(errno.EROFS, os.strerror(errno.EROFS), "/mnt/run/.lock")
    assert paths.os_error_message(read_only).startswith("/mnt/run/.lock: Read-only file system; choose a writable")


def test_tensorboard_on_a_full_disk_raises_once_and_is_not_retried_at_exit(tmp_path, monkeypatch):
    sink = sinks.TensorBoardSink(tmp_path)
    sink.write({"updates": 1, "env_steps": 64, "loss": 0.5})
    (file_writer,) = sink.writer.all_writers.values()
    events = file_writer.event_writer

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(events, "flush", full)
    with pytest.raises(OSError, match="No space left"):
        sink.close()
    assert events._closed and events._worker is not None and not events._worker.is_alive()


def test_an_edited_sweep_json_and_too_many_seeds_are_one_line_before_anything_trains(tmp_path, capsys):
    out = tmp_path / "sweep"
    out.mkdir()
    asked = {"config": "ppo_arm2d_fixed", "seeds": 2, "assignments": ["learning_rate=0.001,0.003"]}
    for edited, problem in [
        ("{", "Expecting property name"),
        ([], "not a JSON object but list"),
        ({"config": "ppo_arm2d_fixed", "seeds": 2}, "no assignments"),
        ({**asked, "assignments": "learning_rate=0.001"}, "assignments must be a list of 'key=v1,v2' strings"),
        ({**asked, "assignments": ["learning_rate=0.001", 3]}, "assignments[1] must be a string, got 3"),
        ({**asked, "seeds": "2"}, "seeds must be an integer, got '2'"),
        ({**asked, "config": None}, "config must be a string, got None"),
    ]:
        (out / "sweep.json").write_text(edited if isinstance(edited, str) else json.dumps(edited))
        assert sweep.main(["--resume", str(out)]) == 2
        (line,) = error_lines(capsys)
        assert line.startswith(f"error: {out / 'sweep.json'} is corrupt or edited (") and problem in line, line
        assert line.endswith("restore it, or start the sweep again in a new directory")
    assert sweep.main(["--config", "ppo_arm2d_fixed", "--seeds", "10000000", "--out", str(tmp_path / "big")]) == 2
    (line,) = error_lines(capsys)
    assert "1 settings × 10000000 seeds × num_envs=" in line and "more than a sweep's group may" in line, line
    assert not (tmp_path / "big").exists()
