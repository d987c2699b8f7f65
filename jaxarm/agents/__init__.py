"""Learners compiled end to end: PPO and TD3 (DDPG is a TD3 setting)."""
