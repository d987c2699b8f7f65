"""A plain-numpy implementation of the arm2d maths, written independently of the JAX env.

It is the reference for the parity tests and the peer in the benchmarks: the classic tutorial's
single-env loop (`ClassicArm`), generalised to N links in the same way as the JAX env. Arrays may carry
leading batch axes, so the same code serves as the numpy-batched peer. It must not import jax.
"""

import numpy as np


class ClassicArm:
    """The tutorial arm in numpy. `angles`: [..., N]; `goal`: [..., 2]; all float32.

    Args mirror Arm2dParams' defaults. Call `reset_to(angles, goal)` then `step(action)`.
    """

    def __init__(
        self,
        link_lengths=(100.0, 100.0),
        base=(200.0, 200.0),
        world=400.0,
        goal_size=40.0,
        action_scale=0.1,
        hold_steps=50,
        success_bonus=0.0,
        max_episode_steps=200,
    ):
        self.link_lengths = np.asarray(link_lengths, np.float32)
        self.base = np.asarray(base, np.float32)
        self.world = np.float32(world)
        self.goal_size = np.float32(goal_size)
        self.action_scale = np.float32(action_scale)
        self.hold_steps = hold_steps
        self.success_bonus = np.float32(success_bonus)
        self.max_episode_steps = max_episode_steps

    def reset_to(self, angles, goal):
        """Starts an episode at the given angles and goal; returns the observation."""
        self.angles = np.asarray(angles, np.float32).copy()
        self.goal = np.asarray(goal, np.float32).copy()
        self.on_goal = np.zeros(self.angles.shape[:-1], np.int64)
        self.steps = 0
        return self.observation()

    def joints(self):
        """[..., N, 2] position of every link end, the finger last."""
        total = np.cumsum(self.angles, axis=-1)
        segments = self.link_lengths[:, None] * np.stack([np.cos(total), np.sin(total)], axis=-1)
        return (self.base + np.cumsum(segments, axis=-2)).astype(np.float32)

    def observation(self):
        joints = self.joints()
        lead = joints.shape[:-2]
        scaled = (joints / (self.world / 2)).reshape(lead + (-1,))
        to_goal = ((self.goal[..., None, :] - joints) / self.world).reshape(lead + (-1,))
        flag = (self.on_goal > 0).astype(np.float32)[..., None]
        return np.concatenate([scaled, to_goal, flag], axis=-1)

    def step(self, action):
        """Returns (observation, reward, terminated, truncated)."""
        action = np.clip(np.asarray(action, np.float32), -1.0, 1.0)
        self.angles = np.mod(self.angles + action * self.action_scale, np.float32(2 * np.pi)).astype(np.float32)
        finger = self.joints()[..., -1, :]
        gap = self.goal - finger
        reward = -np.sqrt(np.sum(gap**2, axis=-1)) / self.world
        inside = np.all(np.abs(gap) < self.goal_size / 2, axis=-1)
        reward = reward + inside
        self.on_goal = np.where(inside, self.on_goal + 1, 0)
        self.steps += 1
        terminated = self.on_goal > self.hold_steps
        reward = reward + self.success_bonus * terminated
        truncated = (self.steps >= self.max_episode_steps) & ~terminated
        return self.observation(), reward.astype(np.float32), terminated, truncated
