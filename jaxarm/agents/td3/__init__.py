"""TD3 and DDPG (TD3 with one critic, no target smoothing, no policy delay), compiled end to end."""

from jaxarm.agents.td3.config import TD3Config
from jaxarm.agents.td3.train import TD3Metrics, TD3State, make_trainer

__all__ = ["TD3Config", "TD3Metrics", "TD3State", "make_trainer"]
