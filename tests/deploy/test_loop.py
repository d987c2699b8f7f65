"""The deployment loop's JAX-free import, Franka's limits and the tick's bookkeeping (no MJX)."""

import inspect
import subprocess
import sys

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxarm.deploy import limits
from jaxarm.deploy.loop import DeploymentLoop, Robot, UnsafeAction
from jaxarm.deploy.mujoco_robot import MujocoRobot
from jaxarm.deploy.reading import ArmReading
from jaxarm.envs.panda.base import ArmOptions
from jaxarm.envs.panda_sort import model as sort_model
from jaxarm.envs.panda_sort.layout import make_layout
from jaxarm.robots import PANDA, robot
from tests.deploy import six_joints


def test_the_deployment_package_imports_no_jax():
    modules = "jaxarm.deploy.loop, jaxarm.deploy.files, jaxarm.deploy.mujoco_robot, jaxarm.export.numpy_policy"
    code = f"import sys, {modules}; print(sorted(m for m in sys.modules if m.split('.')[0] in ('jax', 'flax')))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"


def test_the_envs_and_the_loop_read_the_datasheets_limits():
    loop_limits = inspect.signature(limits.limit_targets).parameters["limits"].default
    assert robot(ArmOptions().robot).joint_limits is loop_limits is PANDA.joint_limits
    np.testing.assert_allclose(PANDA.joint_limits.speed, [2.175] * 4 + [2.61] * 3, rtol=1e-7)
    np.testing.assert_array_equal(PANDA.joint_limits.acceleration, [15, 7.5, 10, 12.5, 15, 20, 20])


def test_targets_are_clipped_to_the_limits():
    period = 0.04
    previous, velocity = np.zeros(7), np.zeros(7)
    # From rest, a 0.1 rad step: every joint's speed is held to its acceleration limit times the period.
    limited = limits.limit_targets(np.full(7, 0.1), previous, velocity, period)
    np.testing.assert_allclose(limited.velocity, PANDA.joint_limits.acceleration * period)
    np.testing.assert_allclose(limited.targets, limited.velocity * period)
    assert limited.acceleration_clipped.all() and not limited.speed_clipped.any()
    # Already at the speed limit, asked for more: the speed limit holds it; a small change passes untouched.
    at_limit = PANDA.joint_limits.speed.astype(np.float64)
    limited = limits.limit_targets(at_limit * period * 1.05, previous, at_limit, period)
    np.testing.assert_allclose(limited.velocity, at_limit)
    assert limited.speed_clipped.all() and not limited.acceleration_clipped.any()
    limited = limits.limit_targets(np.full(7, 0.001), previous, np.full(7, 0.02), period)
    np.testing.assert_allclose(limited.targets, 0.001)
    assert not (limited.speed_clipped.any() or limited.acceleration_clipped.any())


def test_the_envs_clip_their_targets_as_the_loop_does():
    # Joint 1 within the limits, 2 and 3 beyond their acceleration's, 5 and 6 beyond their speed's.
    previous, velocity = np.full(7, 0.3), np.array([0.0, 0.0, 0.0, 0.0, 2.6, 2.6, 0.0])
    targets = previous + np.array([0.001, 0.1, -0.1, 0.01, 0.11, 0.2, 0.0])
    ours = limits.limit_targets(targets, previous, velocity, 0.04)
    as_jax = (jnp.asarray(value) for value in (targets, previous, velocity))
    jitted = jax.jit(limits.limit_targets, static_argnums=3)(*as_jax, 0.04)
    for expected, value in zip(ours, jitted, strict=True):
        np.testing.assert_allclose(np.asarray(value), expected, atol=1e-6)
    assert ours.acceleration_clipped.any() and not ours.acceleration_clipped.all() and ours.speed_clipped.any()


class StepController:
    """Asks every arm joint to jump by `jump` each tick, the fingers (the last 2 targets) kept."""

    action_size = 1

    def __init__(self, jump: float):
        self.jump = jump

    def begin(self) -> None:
        pass

    def observe(self, reading, estimate, ctrl):
        return np.zeros(3, np.float32)

    def act(self, reading, ctrl, action):
        return np.concatenate([ctrl[:-2] + self.jump + action[0], ctrl[-2:]])


def test_the_loop_clips_and_counts():
    reading = ArmReading(np.zeros(7), np.zeros(7), np.zeros(2))
    for clip in (True, False):
        loop = DeploymentLoop(lambda obs: np.zeros(1), StepController(0.2), period=0.04, clip=clip)
        loop.begin(np.zeros(9))
        targets = [loop.tick(reading, None)[:7].copy() for _ in range(20)]
        speed = np.diff(np.stack([np.zeros(7), *targets]), axis=0) / 0.04
        assert len(loop.tick_seconds) == 20
        if clip:
            assert np.all(np.abs(speed) <= PANDA.joint_limits.speed * (1 + 1e-6))
            np.testing.assert_allclose(speed[-1], PANDA.joint_limits.speed, rtol=1e-6)
        else:
            np.testing.assert_allclose(speed, 5.0)
        # 5 rad/s is beyond every joint's speed limit, reached from rest beyond every acceleration limit.
        assert loop.counts.speed.min() >= 10 and loop.counts.acceleration.min() >= 1


def test_the_loop_refuses_an_action_that_is_not_finite_and_sends_nothing():
    reading = ArmReading(np.zeros(7), np.zeros(7), np.zeros(2))
    actions = iter([np.zeros(1), np.array([np.nan]), np.array([np.inf])])
    loop = DeploymentLoop(lambda obs: next(actions), StepController(0.01), period=0.04)
    loop.begin(np.zeros(9))
    sent = loop.tick(reading, None).copy()
    for bad in ("nan", "inf"):
        with pytest.raises(UnsafeAction) as raised:
            loop.tick(reading, None)
        assert f"is not finite ([{bad}]); the robot was stopped at its last targets" in str(raised.value)
        # The robot keeps the last targets it was sent: finite, within the limits.
        np.testing.assert_array_equal(loop.ctrl, sent)


def test_the_loop_drives_stock_mujoco_as_a_robot_on_its_clock():
    mujoco_robot = MujocoRobot(sort_model.build_model(2, make_layout()), period=0.04)
    start = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.8])
    mujoco_robot.data.qpos[:7] = start
    plant: Robot = mujoco_robot
    loop = DeploymentLoop(lambda obs: np.zeros(1), StepController(0.01), period=0.04)
    loop.begin(np.concatenate([start, [0.04, 0.04]]))
    for tick in range(1, 6):
        sent = loop.drive(plant, None)
        # Each tick: the targets sent, then one control period of the robot's clock.
        assert plant.now() == pytest.approx(0.04 * tick)
    np.testing.assert_allclose(sent[:7], start + 0.05)
    assert np.all(plant.reading().arm_q - start > 0.01)


def test_stock_mujoco_leaves_the_scene_posed_where_its_tick_ended_and_its_physics_as_mj_step_makes_it():
    # Scoring reads the sorter's tool and the peg's tip from the scene's poses, which mj_step leaves a timestep
    # behind the qpos it integrated.
    plant = MujocoRobot(sort_model.build_model(2, make_layout()), period=0.04)
    plain = mujoco.MjData(plant.model)
    for data in (plant.data, plain):
        data.qpos[:7] = PANDA.home_qpos
        data.qvel[:7] = 2.0
    for _ in range(3):
        plant.step()
        for _ in range(plant.substeps):
            mujoco.mj_step(plant.model, plain)
    np.testing.assert_array_equal(plant.data.qpos, plain.qpos)
    np.testing.assert_array_equal(plant.data.qvel, plain.qvel)
    mujoco.mj_kinematics(plant.model, plain)
    np.testing.assert_array_equal(plant.data.site_xpos, plain.site_xpos)
    np.testing.assert_array_equal(plant.data.geom_xmat, plain.geom_xmat)


def test_the_loop_and_stock_mujoco_take_a_six_joint_arm_from_its_description():
    description = six_joints.DESCRIPTION
    plant = MujocoRobot(six_joints.scene(), period=0.04, robot=description)
    loop = DeploymentLoop(lambda obs: np.zeros(1), StepController(0.2), period=0.04, description=description)
    assert loop.ctrl.shape == (8,)
    loop.begin(np.zeros(8))
    for _ in range(5):
        sent = loop.drive(plant, None)
    # Asked for 5 rad/s from rest, each tick 10 rad/s² (the 6-joint limits', not the Panda's) faster: 0.016 rad more.
    np.testing.assert_allclose(sent, [0.016 * (1 + 2 + 3 + 4 + 5)] * 6 + [0.0, 0.0])
    assert loop.counts.acceleration.tolist() == [5] * 6 and loop.counts.speed.tolist() == [0] * 6
    np.testing.assert_array_equal(plant.data.ctrl[:6], sent[:6])
    reading = plant.reading()
    assert reading.arm_q.shape == reading.arm_qvel.shape == (6,) and reading.finger_q.shape == (2,)
    assert np.all(reading.arm_q > 0.05)
