"""PPO compiled end to end."""

from jaxarm.agents.ppo.config import PPOConfig
from jaxarm.agents.ppo.networks import PPONetworks, make_networks
from jaxarm.agents.ppo.train import make_trainer

__all__ = ["PPOConfig", "PPONetworks", "make_networks", "make_trainer"]
