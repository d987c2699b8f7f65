"""Learners compile their updates with XLA options chosen by whether the env steps MJX physics."""

import pytest

from jaxarm import _runtime
from jaxarm.agents import ppo, td3
from tests.agents.probe_envs import ConstantRewardEnv


class MjxLikeEnv(ConstantRewardEnv):
    uses_mjx = True


@pytest.mark.parametrize(
    "make_trainer, config",
    [(ppo.make_trainer, ppo.PPOConfig(num_envs=4)), (td3.make_trainer, td3.TD3Config(num_envs=4))],
)
def test_only_programs_without_mjx_turn_the_fusion_emitters_back_on(monkeypatch, make_trainer, config):
    monkeypatch.setattr(_runtime, "_cpu_flag_applied", True)
    plain, mjx_like = ConstantRewardEnv(), MjxLikeEnv()
    assert make_trainer(config, plain, plain.default_params()).compiler_options == {"xla_cpu_use_fusion_emitters": True}
    assert make_trainer(config, mjx_like, mjx_like.default_params()).compiler_options == {}
