"""The learner registry: learners by name and by config, and warm starts only where a learner has one."""

import pathlib

import jax
import numpy as np
import pytest

from jaxarm.agents import registry
from jaxarm.agents.ppo import PPOConfig
from jaxarm.agents.td3 import TD3Config
from jaxarm.runner import learners, rundir


@pytest.mark.parametrize("name", sorted(registry.LEARNERS))
def test_a_learner_is_found_by_its_name_and_by_its_config(name):
    learner = registry.get(name)
    config = learner.config_class()
    assert registry.name_of(config) == name and registry.learner_for(config) is learner


@pytest.mark.parametrize("name", sorted(registry.LEARNERS))
def test_a_state_for_acting_is_the_fresh_state_without_its_envs_and_replay(name):
    config = registry.get(name).config_class(num_envs=2)
    trainer = registry.make_trainer(config)
    key, hparams = jax.random.PRNGKey(3), config.hparams()
    full, acting = trainer.init(key, hparams), trainer.init_for_acting(key, hparams)
    left_out = [field for field in ("env_state", "replay") if hasattr(full, field)]
    assert all(getattr(acting, field) is None for field in left_out)
    kept = acting.replace(**{field: getattr(full, field) for field in left_out})
    for got, want in zip(jax.tree.leaves(kept), jax.tree.leaves(full), strict=True):
        np.testing.assert_array_equal(got, want)
    obs = jax.tree.map(lambda leaf: leaf[:1], full.env_state.obs)
    np.testing.assert_array_equal(trainer.act(acting, obs), trainer.act(full, obs))


def test_an_unknown_learner_names_the_closest():
    with pytest.raises(ValueError, match="did you mean 'td3'"):
        registry.get("td4")


def test_a_teacher_is_read_through_the_registry_where_the_learner_can_be_taught():
    student = PPOConfig(teacher="preset:ppo_arm2d", teacher_overrides=("num_envs=4",))
    assert registry.teacher_of(student) == "preset:ppo_arm2d"
    assert registry.teacher_overrides_of(student) == ("num_envs=4",)
    assert registry.teacher_of(PPOConfig()) == "" and registry.teacher_overrides_of(PPOConfig()) == ()
    assert registry.get("td3").teaching is None
    assert registry.teacher_of(TD3Config()) == "" and registry.teacher_overrides_of(TD3Config()) == ()


def test_a_warm_start_needs_a_learner_that_has_one_and_a_run_of_the_same(tmp_path):
    td3_run = tmp_path / "td3_run"
    rundir.write_config(td3_run, TD3Config(), "td3_arm2d")
    for config in (PPOConfig(init_from=str(td3_run)), TD3Config(init_from=str(td3_run))):
        with pytest.raises(ValueError, match="warm starts exist for ppo only"):
            learners.warm_starter(config, pathlib.Path(config.init_from))
