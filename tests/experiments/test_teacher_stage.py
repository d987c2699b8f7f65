"""A teacher named by preset (`teacher=preset:NAME`): trained into the student's run directory first, reused once
finished, resumed in whichever stage a run stopped, and refused in one line where it cannot serve."""

import dataclasses
import json
import os
import signal

import numpy as np
import pytest

from experiments import configs, run
from experiments.benchmarks.timing import compile_updates
from jaxarm.agents.common.config import apply_overrides
from jaxarm.runner import learners, loop, metrics_log, rundir, teacher

TINY = ["num_envs=16", "rollout_length=4", "num_minibatches=2", "updates_per_chunk=2", "eval_episodes=4"]
"""Both stages at a size that compiles and trains in seconds on a CPU."""
TEACHER_OVERRIDES = (*TINY, "total_env_steps=384", "checkpoint_every_updates=2")
"""The state teacher: 6 updates in 3 chunks, each checkpointed."""


def camera_student(*overrides: str):
    """ppo_arm2d_pixels (16x16 images) distilled from a tiny ppo_arm2d, whose state the privileged part holds."""
    config = apply_overrides(
        configs.get("ppo_arm2d_pixels"),
        [*TINY, "total_env_steps=256", "checkpoint_every_updates=100", "env_kwargs.privileged=true", *overrides],
    )
    return dataclasses.replace(config, teacher="preset:ppo_arm2d", teacher_overrides=TEACHER_OVERRIDES)


def updates_logged(run_dir) -> list[int]:
    return [row["updates"] for row in metrics_log.read_metrics(run_dir)]


def test_a_preset_teacher_trains_first_and_each_stop_resumes_its_own_stage(tmp_path, monkeypatch):
    run_dir = tmp_path / "student"
    teacher_dir = run_dir / rundir.TEACHER_DIR

    # Ctrl-C in the teacher stage (after its first chunk: the stop comes at the next chunk end). The student's
    # config is written first, so the directory resumes as the student's run.
    def interrupt_once(updates):
        if updates == 2:
            os.kill(os.getpid(), signal.SIGINT)

    options = loop.Options(presets=configs.get, on_chunk=interrupt_once)
    with pytest.raises(loop.TrainingInterrupted) as interrupted:
        loop.train(camera_student(), run_dir, options=options)
    assert interrupted.value.resume_dir == run_dir and updates_logged(teacher_dir) == [1, 2, 3, 4]
    assert rundir.read_config(run_dir)[0].teacher == "preset:ppo_arm2d"
    assert not (run_dir / "checkpoints").exists()

    # Stopped between the stages (as a kill would, before the student's first program compiled). A started
    # teacher is read back from its own directory: no lookup of presets is needed to resume it.
    make_trainer = learners.make_trainer

    def stop_at_the_student(config, run_dir=None):
        if teacher.teacher_preset(config):
            raise loop.TrainingInterrupted("stopped between the stages")
        return make_trainer(config, run_dir)

    monkeypatch.setattr(learners, "make_trainer", stop_at_the_student)
    with pytest.raises(loop.TrainingInterrupted):
        loop.resume(run_dir)
    monkeypatch.undo()
    assert json.loads((teacher_dir / "eval.json").read_text())["finished"]
    assert updates_logged(teacher_dir) == [1, 2, 3, 4, 5, 6]
    assert sorted(path.name for path in run_dir.iterdir()) == [".lock", "config.json", rundir.TEACHER_DIR]
    teacher_files = {path: path.stat().st_mtime_ns for path in teacher_dir.rglob("*") if path.is_file()}

    result, config = loop.resume(run_dir)
    assert result["finished"] and updates_logged(run_dir) == [1, 2, 3, 4]
    assert json.loads((run_dir / "eval.json").read_text()) == result and result["episodes"] == 4
    assert all(row["loss/imitation"] > 0 for row in metrics_log.read_metrics(run_dir))
    assert {path: path.stat().st_mtime_ns for path in teacher_files} == teacher_files, "the finished teacher is reused"
    assert loop.load_run(run_dir)[0] == config
    assert loop.resume(run_dir)[0] == result, "a finished run is left as it is"


def test_a_run_without_a_preset_teacher_reaches_its_learner_without_the_teacher_stage(tmp_path, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("a run without a preset teacher entered the teacher stage")

    monkeypatch.setattr(teacher, "train_stage", never)
    monkeypatch.setattr(loop, "_train_learner", lambda config, *rest: {"learner of": config.env})
    assert loop.train(apply_overrides(configs.get("ppo_arm2d"), TINY), tmp_path / "run") == {"learner of": "arm2d"}


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["teacher=preset:ppo_arm2dd"], "teacher=preset:ppo_arm2dd: unknown config 'ppo_arm2dd' (did you mean"),
        (["teacher=preset:ppo_arm2d", "env_kwargs.privileged=false"], "needs env_kwargs.privileged=true"),
        (["teacher=preset:ppo_arm2d", "teacher_overrides=num_envz=4"], "teacher=preset:ppo_arm2d: unknown config key"),
        (["teacher=preset:"], "teacher=preset: names no preset"),
        (["teacher_overrides=num_envs=4"], "teacher_overrides apply to a teacher named by preset"),
    ],
)
def test_a_teacher_that_cannot_serve_is_refused_in_one_line_before_anything_is_written(
    tmp_path, capsys, overrides, message
):
    out = tmp_path / "refused"
    student = ["--config", "ppo_arm2d_pixels", "env_kwargs.privileged=true", *overrides, "--out", str(out)]
    assert run.main(student) == 2
    error = capsys.readouterr().err
    assert message in error and error.count("\n") == 1
    assert not out.exists()


def test_a_benchmark_compiles_a_students_update_with_its_preset_teacher_untrained():
    compiled, state, hparams, seconds = compile_updates(camera_student(), num_updates=1)
    state, metrics = compiled(state, hparams)
    assert seconds > 0 and np.isfinite(float(metrics.loss.imitation[-1]))
