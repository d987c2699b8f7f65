"""PPO presets. Each setting that differs from PPOConfig's defaults says why."""

import dataclasses

from jaxarm.agents.ppo import PPOConfig
from jaxarm.envs.arm2d import GOAL_UNIFORM_REACHABLE
from experiments.configs import preset

# Measured on the 2-core CPU (deterministic success on 1,000 fresh episodes, random reachable goals):
# - γ: at 2M steps and lr 1e-3, γ 0.99 gave 36% and γ 0.95 72%; the goal is held ~50 steps and then the
#   episode ends, and a short horizon keeps value targets small. γ 0.9 with lr 3e-3 gave 80% at 2M.
# - success_bonus 10 (reward when the hold completes): without it the best return comes from leaving the
#   goal for a step to restart the hold count (return 54 with 83% success at 2M steps); with it, 100% at
#   1.5M steps.
# - 1,024 envs × 16 steps per update: twice the updates per env step of 2,048 envs at the same throughput
#   (51% vs 36% at 2M steps, lr 1e-3); lr 3e-3 beat 1e-3 (91% vs 51%).
ARM2D_PPO = PPOConfig(
    env="arm2d",
    env_params=(("success_bonus", 10.0),),
    num_envs=1024,
    rollout_length=16,
    num_minibatches=4,
    gamma=0.9,
    learning_rate=3e-3,
    updates_per_chunk=20,
    checkpoint_every_updates=40,
)


@preset("PPO on arm2d with random goals over the reachable disc (2-core CPU: under a minute)")
def ppo_arm2d() -> PPOConfig:
    return dataclasses.replace(
        ARM2D_PPO, env_params=(("goal_mode", GOAL_UNIFORM_REACHABLE), ("success_bonus", 10.0)), total_env_steps=1_500_000
    )


@preset("PPO on arm2d with the tutorial's fixed goal at (100, 100)")
def ppo_arm2d_fixed() -> PPOConfig:
    return dataclasses.replace(ARM2D_PPO, total_env_steps=1_000_000)
