"""Commands a real Franka accepts: with Franka's dynamics and the running target, the servos' targets keep every
joint within the datasheet's speed limits, and a held unit yaw or wrist action gets its step soon and stops where
its steps add up to. Measured from outside through the observation (the arm's angles and the servos' lead)."""

import os

os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.panda.dynamics import IDENTIFIED
from jaxarm.envs.panda.robot import yaw_of_quaternion
from jaxarm.envs.panda_sort import MODE_JOINT, PandaSort
from jaxarm.envs.panda_sort.env import OBJECT_OBS_SIZE
from jaxarm.robots import PANDA
from tests.envs.compiled import same_worker

PANDA_JOINTS = len(PANDA.arm_joints)
"""The Panda's arm joints: the servos' lead a running-target sorter observes, one per joint."""

pytestmark = [pytest.mark.mjx, pytest.mark.slow, same_worker("panda_sort_servo_limits")]
TOOL = OBJECT_OBS_SIZE  # one object: the tool's part starts after its row
ARM = slice(TOOL + 14, TOOL + 21)  # after position 3, quaternion 4, velocities 6 and the finger width 1
HELD, STEPS = 12, 30
"""A held action's steps, then the steps without it in which the arm comes to rest."""
REACHED_WITHIN = 8
"""Steps by which a held unit action's motion per step must reach 85% of its step."""


def rollouts(env: PandaSort, actions: np.ndarray) -> np.ndarray:
    """[B, T + 1, O] observations from one reset and the action sequences `actions` [B, T, A], one program."""
    params = env.default_params()

    @jax.jit
    def rollout(actions):
        start = env.reset(jax.random.key(0), params)

        def step(state, action):
            state = env.step(state, action, params)
            return state, state.obs

        return jnp.concatenate([start.obs[None], jax.lax.scan(step, start, actions)[1]])

    return np.asarray(jax.vmap(rollout)(jnp.asarray(actions)))


def held(action: np.ndarray) -> np.ndarray:
    """[STEPS, A]: `action` for HELD steps, then the same with the arm still (the fingers' entry kept)."""
    still = np.r_[np.zeros(len(action) - 1), action[-1]]
    return np.stack([action] * HELD + [still] * (STEPS - HELD)).astype(np.float32)


def random_actions(size: int) -> np.ndarray:
    return np.random.default_rng(0).uniform(-1.0, 1.0, (STEPS, size)).astype(np.float32)


def commanded_speeds(obs: np.ndarray) -> np.ndarray:
    """[T, 7] the servos' targets' speed each step: the observed angles plus the observed lead."""
    targets = obs[:, ARM] + obs[:, -PANDA_JOINTS:]
    return np.abs(np.diff(targets, axis=0)) / CONTROL_DT


def check_held_motion(motion: np.ndarray, step: float) -> None:
    """A held unit action's motion per step [STEPS] along its own coordinate: 85% of `step` within
    REACHED_WITHIN steps, and in all no more than 5% beyond HELD steps of it."""
    assert np.any(motion[:REACHED_WITHIN] >= 0.85 * step), motion / step
    assert 0.9 < np.sum(motion) / (HELD * step) < 1.05, motion / step


@pytest.fixture(scope="module")
def ee_rollouts():
    """ee mode: a held unit yaw (hand turning), a held unit move along x, random actions (uniform in [-1, 1])."""
    env = PandaSort(objects_count=1, running_target=True, dynamics=IDENTIFIED)
    actions = np.stack([held(np.array([0, 0, 0, 1.0, 1.0])), held(np.array([1.0, 0, 0, 0, 1.0])), random_actions(5)])
    return env.default_params(), rollouts(env, actions)


@pytest.fixture(scope="module")
def joint_rollouts():
    """joint mode: each wrist joint (5, 6, 7) held at a unit action away from its nearer limit, then the base (joint
    1) held at a unit action, which asks for 2.5 rad/s (joint_step 0.1 rad per 0.04 s) against its limit 2.175."""
    env = PandaSort(objects_count=1, control_mode=MODE_JOINT, running_target=True, dynamics=IDENTIFIED)
    signs = {4: 1.0, 5: -1.0, 6: -1.0}
    actions = [held(np.eye(8)[joint] * sign + np.eye(8)[7]) for joint, sign in signs.items()]
    return env.default_params(), signs, rollouts(env, np.stack([*actions, held(np.eye(8)[0] + np.eye(8)[7])]))


def test_a_held_yaw_turns_the_hand_by_its_step_and_stops_where_told(ee_rollouts):
    params, obs = ee_rollouts
    yaw = np.unwrap(np.asarray(yaw_of_quaternion(obs[0, :, TOOL + 3 : TOOL + 7])))
    check_held_motion(np.diff(yaw), float(params.ee_yaw_step))
    x = obs[1, :, TOOL]
    check_held_motion(np.diff(x), float(params.ee_step))


def test_a_held_wrist_action_turns_the_joint_by_its_step_and_stops_where_told(joint_rollouts):
    params, signs, obs = joint_rollouts
    for row, (joint, sign) in enumerate(signs.items()):
        check_held_motion(sign * np.diff(obs[row, :, ARM][:, joint]), float(params.joint_step))


def test_the_servos_targets_stay_within_franka_speed_limits(ee_rollouts, joint_rollouts):
    for obs in (ee_rollouts[1], joint_rollouts[2]):
        speeds = np.concatenate([commanded_speeds(episode) for episode in obs])
        assert np.all(speeds <= PANDA.joint_limits.speed * (1 + 1e-4)), speeds.max(0)
    # The base, asked for more than its limit, moves at the limit: the limits, not the actions' size, hold it.
    assert commanded_speeds(joint_rollouts[2][-1])[:, 0].max() > 0.99 * PANDA.joint_limits.speed[0]
