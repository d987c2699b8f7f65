"""The franky-control and ur_rtde adapters against stand-ins of those drivers' APIs (no hardware here): what each
tick sends, what a reading reports, and the hold that brakes and stops."""

import types

import numpy as np

from jaxarm.deploy.adapters import GRIPPER_DEADBAND, FrankyRobot, RtdeRobot
from jaxarm.deploy.loop import Robot

PERIOD = 0.04


class FakeFrankyArm:
    def __init__(self):
        self.current_joint_state = types.SimpleNamespace(position=np.arange(7.0), velocity=np.ones(7))
        self.moves: list = []
        self.joined = False

    def move(self, motion, asynchronous=False):
        assert asynchronous, "a blocking move would stop the loop's ticks"
        self.moves.append(motion)

    def join_motion(self, timeout=None):
        self.joined = True
        return True


class FakeGripper:
    width = 0.06

    def __init__(self):
        self.widths: list[float] = []

    def move_async(self, width, speed):
        self.widths.append(width)


FAKE_FRANKY = types.SimpleNamespace(
    JointState=lambda position, velocity: ("state", position.copy(), velocity.copy()),
    JointMotion=lambda target: ("motion", target),
    JointStopMotion=lambda: ("stop",),
)
"""franky's motion and state classes, as tuples that say what they were made with."""


def test_franky_sends_each_ticks_targets_at_the_loops_rate_and_widths_past_the_deadband():
    arm, gripper = FakeFrankyArm(), FakeGripper()
    franky = FrankyRobot(arm, gripper, FAKE_FRANKY, PERIOD)
    robot: Robot = franky
    reading = robot.reading()
    np.testing.assert_array_equal(reading.arm_q, np.arange(7.0))
    np.testing.assert_allclose(reading.finger_q, [0.03, 0.03])
    start = np.concatenate([np.zeros(7), [0.02, 0.02]])
    robot.command(start)
    robot.command(start + np.concatenate([np.full(7, 0.01), [GRIPPER_DEADBAND / 4] * 2]))
    robot.command(start + np.concatenate([np.full(7, 0.03), [GRIPPER_DEADBAND] * 2]))
    # The first tick's targets arrive at rest; the last's at the rate from the tick before.
    (_, (_, _, first_velocity)), _, (_, (_, last, velocity)) = arm.moves
    np.testing.assert_array_equal(first_velocity, 0.0)
    np.testing.assert_allclose(last, 0.03)
    np.testing.assert_allclose(velocity, 0.02 / PERIOD)
    # The second width was within the deadband of the first: not sent.
    np.testing.assert_allclose(gripper.widths, [0.04, 0.04 + 2 * GRIPPER_DEADBAND])
    franky.hold()
    assert arm.moves[-1] == ("stop",) and arm.joined


class FakeRtde:
    def __init__(self):
        self.calls: list = []

    def servoJ(self, q, speed, acceleration, time, lookahead_time, gain):
        self.calls.append(("servoJ", q, time, lookahead_time, gain))
        return True

    def servoStop(self, a=10.0):
        self.calls.append(("servoStop",))
        return True

    def stopScript(self):
        self.calls.append(("stopScript",))

    def getActualQ(self):
        return [0.1] * 6

    def getActualQd(self):
        return [0.0] * 6


def test_ur_rtde_servos_six_joints_over_the_control_period_then_stops():
    rtde = FakeRtde()
    robot = RtdeRobot(rtde, rtde, PERIOD)
    reading = robot.reading()
    assert reading.arm_q.shape == (6,) and reading.finger_q.shape == (0,)
    robot.command(np.arange(9.0))
    robot.hold()
    assert rtde.calls == [
        ("servoJ", [0.0, 1.0, 2.0, 3.0, 4.0, 5.0], PERIOD, 0.1, 300.0),
        ("servoStop",),
        ("stopScript",),
    ]
