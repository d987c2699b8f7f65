"""PPO compiled end to end."""

from jaxarm.agents.ppo.config import PPOConfig, PPOHParams
from jaxarm.agents.ppo.train import make_trainer

__all__ = ["PPOConfig", "PPOHParams", "make_trainer"]
