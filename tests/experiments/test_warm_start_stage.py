"""A warm start named by preset (`init_from=preset:NAME`): that preset trained into the run's warm_start/ first, with
the run's seed, in the same command, and again for each try where a gated run asks it (`retry_warm_start`); refused
in one line where it cannot serve."""

import json

import pytest

from experiments import configs
from jaxarm.agents.common.config import apply_overrides
from jaxarm.runner import loop, metrics_log, rundir, teacher, tries

TINY = [
    "num_envs=16",
    "rollout_length=4",
    "num_minibatches=2",
    "updates_per_chunk=2",
    "eval_episodes=4",
    "total_env_steps=128",
    "checkpoint_every_updates=2",
]
"""Both stages at a size that compiles and trains in seconds on a CPU."""


def tiny_preset(name: str):
    return apply_overrides(configs.get(name), TINY)


def test_a_preset_warm_start_trains_first_with_the_runs_seed_then_the_run(tmp_path):
    run_dir = tmp_path / "warm"
    config = apply_overrides(tiny_preset("ppo_arm2d_fixed"), ["init_from=preset:ppo_arm2d_fixed", "seed=3"])
    result = loop.train(config, run_dir, options=loop.Options(presets=tiny_preset))
    stage_dir = run_dir / rundir.WARM_START_DIR
    stage, stage_preset = rundir.read_config(stage_dir)
    assert stage_preset == "ppo_arm2d_fixed" and stage.seed == 3 and stage.init_from == ""
    assert json.loads((stage_dir / "eval.json").read_text())["finished"]
    assert result["finished"] and rundir.read_config(run_dir)[0].init_from == "preset:ppo_arm2d_fixed"
    # Resumed once finished, neither stage trains again.
    assert loop.resume(run_dir)[0] == result


RETRIED = [
    "init_from=preset:ppo_arm2d_fixed",
    "seed=3",
    "total_env_steps=256",
    "eval_every_updates=2",
    "retry_below=1.0",
    "retry_at_env_steps=64",
    "tries=2",
    "retry_warm_start=true",
]
"""A run whose first try fails its gate at update 2 (its evaluations are below 100% there), each try training its
warm start first."""


def test_a_try_that_fails_its_gate_trains_its_warm_start_again_with_a_seed_of_its_own(tmp_path, capsys):
    run_dir = tmp_path / "retried"
    config = apply_overrides(tiny_preset("ppo_arm2d_fixed"), RETRIED)
    result = loop.train(config, run_dir, options=loop.Options(presets=tiny_preset))
    assert "starting try 2, its warm start trained again first" in capsys.readouterr().err
    set_aside = run_dir / tries.TRIES_DIR / "0"
    first, second = (rundir.read_config(folder / rundir.WARM_START_DIR)[0] for folder in (set_aside, run_dir))
    assert first.seed == 3 and second.seed == tries.warm_start_seed(3, 1) != 3
    for stage in (set_aside, run_dir):
        assert json.loads((stage / rundir.WARM_START_DIR / "eval.json").read_text())["finished"]
    # The failed try stopped at its gate (update 2); the last trained to its end, its clock after the first's.
    failed, rows = metrics_log.read_metrics(set_aside), metrics_log.read_metrics(run_dir)
    assert [row["updates"] for row in failed] == [1, 2] and [row["updates"] for row in rows] == [1, 2, 3, 4]
    assert rows[0]["wall_time"] > failed[-1]["wall_time"]
    assert result["finished"] and result["tries"] == 2
    # Resumed once finished, nothing trains again.
    assert loop.resume(run_dir)[0] == result


def test_a_run_stopped_in_any_stage_of_its_second_try_resumes_there(tmp_path):
    run_dir = tmp_path / "stopped"
    # Each command stops after its first chunk, in whichever stage it is; a warm start takes two chunks: the
    # commands stop in the first warm start, then in the second, then in the second try.
    stopping = loop.Options(
        presets=lambda name: apply_overrides(tiny_preset(name), ["updates_per_chunk=1"]), stop_after_s=0.0
    )
    result = loop.train(apply_overrides(tiny_preset("ppo_arm2d_fixed"), RETRIED), run_dir, options=stopping)
    commands = 1
    while not result["finished"]:
        result, _ = loop.resume(run_dir, options=stopping)
        commands += 1
    assert commands == 4 and result["tries"] == 2 and tries.tries_set_aside(run_dir) == 1
    assert rundir.read_config(run_dir / rundir.WARM_START_DIR)[0].seed == tries.warm_start_seed(3, 1)
    failed, rows = metrics_log.read_metrics(run_dir / tries.TRIES_DIR / "0"), metrics_log.read_metrics(run_dir)
    assert [row["updates"] for row in rows] == [1, 2, 3, 4]
    # Stopped between its tries, the run keeps its records and counts the failed try's time in its clock.
    records = json.loads((run_dir / rundir.PROVENANCE_FILE).read_text())["records"]
    assert [record["event"] for record in records] == ["start", "try 2", "resume"]
    assert rows[0]["wall_time"] > failed[-1]["wall_time"]


def test_a_student_kickstarted_by_its_warm_start_is_taught_by_the_run_it_starts_from(tmp_path):
    run_dir = tmp_path / "kickstarted"
    kickstart = ["teacher=init_from", "imitation_only=false", "imitation_decay_updates=2", "total_env_steps=256"]
    config = apply_overrides(tiny_preset("ppo_arm2d_fixed"), ["init_from=preset:ppo_arm2d_fixed", *kickstart])
    assert teacher.teacher_run(config, run_dir) == run_dir / rundir.WARM_START_DIR
    with pytest.raises(rundir.RunDirError, match="trained into the student's run directory"):
        teacher.teacher_run(config, None)
    # A warm start trained long enough to act apart from a fresh policy.
    longer = loop.Options(presets=lambda name: apply_overrides(tiny_preset(name), ["total_env_steps=4096"]))
    result = loop.train(config, run_dir, options=longer)
    assert result["finished"] and not (run_dir / rundir.TEACHER_DIR).exists()
    # From a run directory, that run teaches.
    warm_start = run_dir / rundir.WARM_START_DIR
    assert teacher.teacher_run(apply_overrides(config, [f"init_from={warm_start}"]), None) == warm_start
    # The student starts as its teacher acts: far closer to it than a fresh student taught by the same run.
    fresh_dir = tmp_path / "fresh"
    fresh = apply_overrides(tiny_preset("ppo_arm2d_fixed"), [*kickstart[1:], f"teacher={warm_start}"])
    loop.train(fresh, fresh_dir, options=loop.Options(presets=tiny_preset))
    kickstarted, taught = (metrics_log.read_metrics(path)[0]["loss/imitation"] for path in (run_dir, fresh_dir))
    assert kickstarted < 0.05 * taught, (kickstarted, taught)


@pytest.mark.parametrize(
    ("init_from", "message"),
    [
        ("preset:ppo_arm2d_fixd", "ppo_arm2d_fixed"),  # the closest preset named
        ("preset:td3_arm2d", "warm-starts from a run of its own learner"),
    ],
)
def test_a_warm_start_preset_that_cannot_serve_is_refused_before_anything_is_written(tmp_path, init_from, message):
    run_dir = tmp_path / "refused"
    config = apply_overrides(tiny_preset("ppo_arm2d_fixed"), [f"init_from={init_from}"])
    with pytest.raises(ValueError, match=message):
        loop.train(config, run_dir, options=loop.Options(presets=configs.get))
    assert not (run_dir / "config.json").exists()
