"""The learner registry: learners by name and by config, and warm starts only where a learner has one."""

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


def test_an_unknown_learner_names_the_closest():
    with pytest.raises(ValueError, match="did you mean 'td3'"):
        registry.get("td4")


def test_a_warm_start_needs_a_learner_that_has_one_and_a_run_of_the_same(tmp_path):
    td3_run = tmp_path / "td3_run"
    rundir.write_config(td3_run, TD3Config(), "td3_arm2d")
    for config in (PPOConfig(init_from=str(td3_run)), TD3Config(init_from=str(td3_run))):
        with pytest.raises(ValueError, match="warm starts exist for ppo only"):
            learners.warm_starter(config)
