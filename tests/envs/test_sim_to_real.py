"""The sim-to-real pieces of the Panda envs on hand-worked numbers (eager, no MJX program): queued actions,
servo gains and damping, observation noise."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxarm.envs.panda.base import ArmOptions
from jaxarm.envs.panda.sim_to_real import delayed_action, with_noise, with_servo_scales
from jaxarm.envs.panda_sort import PandaSort
from jaxarm.envs.peg_insert import PegInsert


@pytest.mark.parametrize(("latency", "applied"), [(0, 0.0), (1, 1.0), (2, 2.0), (5, 2.0)])
def test_the_servos_receive_the_action_of_latency_steps_ago(latency, applied):
    queued = jnp.array([[1.0], [2.0]])  # newest first
    action, queue = delayed_action(queued, jnp.array([0.0]), jnp.int32(latency))
    assert float(action[0]) == applied
    np.testing.assert_array_equal(queue, [[0.0], [1.0]])


def test_without_a_queue_the_action_applies_at_once():
    action, queue = delayed_action(jnp.zeros((0, 3)), jnp.array([1.0, 2.0, 3.0]), jnp.int32(1))
    np.testing.assert_array_equal(action, [1.0, 2.0, 3.0])
    assert queue.shape == (0, 3)


def test_servo_scales_reach_the_arm_servos_and_joints_alone():
    env = PandaSort()
    model, robot = env.mjx_model, env.ids.robot
    scaled = with_servo_scales(model, robot, jnp.float32(2.0), jnp.float32(3.0))
    arm, fingers = robot.arm_actuators, np.setdiff1d(np.arange(env.mj_model.nu), robot.arm_actuators)
    np.testing.assert_allclose(scaled.actuator_gainprm[arm, 0], 2 * np.asarray(model.actuator_gainprm[arm, 0]))
    np.testing.assert_allclose(scaled.actuator_biasprm[arm, 1], 2 * np.asarray(model.actuator_biasprm[arm, 1]))
    np.testing.assert_allclose(scaled.actuator_biasprm[arm, 2], 3 * np.asarray(model.actuator_biasprm[arm, 2]))
    np.testing.assert_allclose(scaled.dof_damping[robot.arm_qpos], 3 * np.asarray(model.dof_damping[robot.arm_qpos]))
    for field in ("actuator_gainprm", "actuator_biasprm"):
        np.testing.assert_array_equal(getattr(scaled, field)[fingers], getattr(model, field)[fingers])
    np.testing.assert_array_equal(scaled.dof_damping[robot.finger_qpos], model.dof_damping[robot.finger_qpos])


def test_noise_has_the_asked_spread_and_none_at_zero():
    values = jnp.linspace(-1.0, 1.0, 20_000)
    key = jax.random.key(0)
    np.testing.assert_array_equal(with_noise(values, key, jnp.float32(0.0)), values)
    assert float(jnp.std(with_noise(values, key, jnp.float32(0.01)) - values)) == pytest.approx(0.01, rel=0.05)


@pytest.mark.parametrize("task", [PandaSort, PegInsert])
def test_a_negative_latency_bound_is_refused(task):
    with pytest.raises(ValueError, match="max_action_latency"):
        task(options=ArmOptions(max_action_latency=-1))
