"""Learners compiled end to end: PPO and TD3 (DDPG is a TD3 setting)."""

from jaxarm._runtime import import_mjx_quietly

import_mjx_quietly()  # before brax, which imports mujoco.mjx
