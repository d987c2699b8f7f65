"""`running_target`: the sorter's actions are the motion they get, measured from outside through the observation.

Without it each step's target starts from the measured pose and the servos cover about a third of it (the tool
moves 6.4-6.8 mm per step for ee_step = 2 cm); with it the target the servos chase moves by the action, held
within the params' leads of the measured pose.
"""

import os

os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.envs.panda.base import CONTROL_DT
from jaxarm.envs.panda.robot import wrapped_angle, yaw_of_quaternion
from jaxarm.envs.panda_sort import MODE_JOINT, PandaSort
from jaxarm.envs.panda_sort.env import OBJECT_OBS_SIZE, TOOL_POSE_OBS_SIZE
from jaxarm.robots import PANDA
from tests.envs.compiled import same_worker

PANDA_JOINTS = len(PANDA.arm_joints)
"""The Panda's arm joints: the servos' lead a running-target sorter observes, one per joint."""

pytestmark = [pytest.mark.mjx, same_worker("panda_sort_running_target")]
TOOL = OBJECT_OBS_SIZE  # one object: the tool's part starts after its row


def observations(env: PandaSort, action: np.ndarray, steps: int) -> np.ndarray:
    """[steps + 1, O] observations from a reset and `steps` steps of the constant `action`, one program."""
    params = env.default_params()

    @jax.jit
    def rollout(key):
        start = env.reset(key, params)

        def step(state, _):
            state = env.step(state, jnp.asarray(action), params)
            return state, state.obs

        return jnp.concatenate([start.obs[None], jax.lax.scan(step, start, None, length=steps)[1]])

    return np.asarray(rollout(jax.random.key(0)))


def test_ee_actions_move_the_tool_and_turn_the_hand_by_their_steps():
    env = PandaSort(objects_count=1, running_target=True)
    params = env.default_params()
    assert env.spec.observation_shape == (OBJECT_OBS_SIZE + (TOOL_POSE_OBS_SIZE + PANDA_JOINTS) + PANDA_JOINTS,)
    # Half speed towards the robot and a half-speed turn, fingers open, for a second.
    obs = observations(env, np.array([-0.5, 0.0, 0.0, 0.5, 1.0], np.float32), 25)
    tcp = obs[:, TOOL : TOOL + 3]
    motion = np.diff(tcp, axis=0)
    # Under way (from step 10; the servos take ~8 steps to reach speed) the tool moves half an ee_step per step,
    # and not sideways. Without running_target it moved a third of that.
    assert np.allclose(motion[10:, 0], -0.5 * float(params.ee_step), rtol=0.05), motion[:, 0]
    assert np.all(np.abs(motion[10:, 1:]) < 0.05 * float(params.ee_step)), motion[:, 1:]
    # The wrist, slow to accelerate, falls behind and then catches up: over the second the hand turns as asked.
    yaw = np.unwrap(np.asarray(yaw_of_quaternion(obs[:, TOOL + 3 : TOOL + 7])))
    assert yaw[-1] - yaw[0] == pytest.approx(25 * 0.5 * float(params.ee_yaw_step), rel=0.1)
    # The observation's last part is the servos' lead, bounded by how far the targets may run ahead.
    lead = obs[:, -PANDA_JOINTS:]
    assert np.all(lead[0] == 0.0) and np.any(np.abs(lead[-1]) > 1e-3)


def test_joint_actions_move_the_joint_by_joint_step_and_the_lead_stays_bounded():
    env = PandaSort(objects_count=1, control_mode=MODE_JOINT, running_target=True)
    params = env.default_params()
    arm = slice(TOOL + 14, TOOL + 21)  # after position 3, quaternion 4, velocities 6 and the finger width 1
    obs = observations(env, np.array([1.0, 0, 0, 0, 0, 0, 0, 1.0], np.float32), 12)
    turn = np.diff(obs[:, arm][:, 0])
    # A unit action asks the base for joint_step per step, 2.5 rad/s; under way (from step 9, its acceleration
    # limit and its servo's lag behind) it turns at its speed limit.
    asked = min(float(params.joint_step), float(PANDA.joint_limits.speed[0]) * CONTROL_DT)
    assert np.allclose(turn[9:], asked, rtol=0.02), turn
    lead = obs[:, -PANDA_JOINTS:]
    assert np.all(np.abs(lead) <= float(params.max_joint_lead) + 1e-6)
    # Asked to turn the wrist faster than it can (1 rad in 10 steps; it turns ~0.5), the target stops
    # max_joint_lead ahead of the angle it starts each step from instead of running away: the lead observed
    # after the step's motion stays below it (unbounded, it reached 0.44 by step 6 and 0.56 by step 10).
    # Turned down: the wrist starts near its upper limit.
    fast = observations(env, np.array([0, 0, 0, 0, 0, 0, -1.0, 1.0], np.float32), 10)
    wrist_lead = fast[:, -1]
    assert np.all(np.abs(wrist_lead) < float(params.max_joint_lead)), wrist_lead


def test_warm_starts_map_the_tool_and_leave_the_lead_new():
    plain, running = PandaSort(objects_count=1), PandaSort(objects_count=1, running_target=True)
    shared = OBJECT_OBS_SIZE + (TOOL_POSE_OBS_SIZE + PANDA_JOINTS)
    into_running = running.observation_source_index(plain)
    assert np.array_equal(into_running, np.r_[np.arange(shared), np.full(PANDA_JOINTS, -1)])
    assert np.array_equal(plain.observation_source_index(running), np.arange(shared))
    assert np.array_equal(running.observation_source_index(running), np.arange(shared + PANDA_JOINTS))


def test_wrapped_angle():
    assert np.allclose(
        wrapped_angle(jnp.array([0.0, 3 * np.pi / 2, -3 * np.pi / 2, 7.0])),
        [0.0, -np.pi / 2, np.pi / 2, 7.0 - 2 * np.pi],
    )
