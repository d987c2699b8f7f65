"""A warm start named by preset (`init_from=preset:NAME`): that preset trained into the run's warm_start/ first, with
the run's seed, in the same command; refused in one line where it cannot serve."""

import json

import pytest

from experiments import configs
from jaxarm.agents.common.config import apply_overrides
from jaxarm.runner import loop, rundir

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
