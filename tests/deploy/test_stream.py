"""The jerk-limited servo stream: 25 Hz targets within the loop's limits -> 1 kHz setpoints within Franka's speed,
acceleration and jerk limits, which reach the targets and brake to rest on `hold`."""

import numpy as np

from jaxarm.deploy import limits, wire
from jaxarm.deploy.stream import ServoStream, limit_ratios
from tests.deploy import six_joints

TIMING = wire.Timing()
SERVO_TICKS = round(TIMING.control_period / TIMING.servo_period)


def loop_targets(rng: np.random.Generator, ticks: int):
    """[ticks] (targets [7], velocity [7]) the loop sends for random asked targets: clipped to the 25 Hz limits."""
    previous, velocity, sent = np.zeros(7), np.zeros(7), []
    for _ in range(ticks):
        limited = limits.limit_targets(previous + rng.uniform(-0.15, 0.15, 7), previous, velocity, 0.04)
        previous, velocity = limited.targets, limited.velocity
        sent.append((previous, velocity))
    return sent


def stream_of(stream: ServoStream, targets) -> list:
    points = []
    for target, velocity in targets:
        stream.retarget(target, velocity)
        points += [stream.next() for _ in range(SERVO_TICKS)]
    return points


def test_no_setpoint_goes_beyond_frankas_limits_and_hold_brakes_to_rest():
    # Random targets flip each joint's acceleration every tick: the stream's hardest case, at every limit.
    stream = ServoStream(np.zeros(7), TIMING.servo_period, TIMING.arrival)
    points = stream_of(stream, loop_targets(np.random.default_rng(0), 50))
    stream.hold()
    stream.retarget(np.ones(7), np.ones(7))  # ignored once holding
    while not stream.at_rest:
        points.append(stream.next())
    velocity = np.array([point.velocity for point in points])
    acceleration = np.array([point.acceleration for point in points])
    ratios = limit_ratios(velocity, acceleration, TIMING.servo_period)
    for name, ratio in ratios.items():
        assert np.all(ratio <= 1 + 1e-9), (name, ratio)
        assert ratio.max() > 0.99, (name, ratio)  # each limit binds: the test is not vacuous
    # Braking takes less than 0.6 s: Franka's slowest stop from full speed is 0.29 s (joint 2: 2.175 rad/s at
    # 7.5 rad/s²), and the jerk limit adds its ramps.
    assert len(points) - 50 * SERVO_TICKS < 600
    np.testing.assert_allclose(points[-1].velocity, 0.0, atol=1e-12)


def test_the_stream_reaches_a_target_held_still():
    stream = ServoStream(np.zeros(7), TIMING.servo_period, TIMING.arrival)
    target = np.array([0.3, -0.2, 0.1, 0.4, -0.5, 0.2, 0.6])
    points = stream_of(stream, [(target, np.zeros(7))] * 25)
    np.testing.assert_allclose(points[-1].position, target, atol=1e-9)
    np.testing.assert_allclose(points[-1].velocity, 0.0, atol=1e-9)
    # A small step (within the jerk limits in 10 ms) is reached at the arrival time, half a control period, not sooner.
    stream = ServoStream(np.zeros(7), TIMING.servo_period, TIMING.arrival)
    points = stream_of(stream, [(np.full(7, 1e-4), np.zeros(7))])
    reached = [np.allclose(point.position, 1e-4, atol=1e-12) for point in points]
    assert reached.index(True) == round(TIMING.arrival / TIMING.servo_period) - 1


def test_a_six_joint_stream_takes_its_joint_count_and_limits_from_them():
    limits = six_joints.LIMITS
    stream = ServoStream(np.zeros(6), TIMING.servo_period, TIMING.arrival, limits)
    target = np.array([0.3, -0.2, 0.1, 0.4, -0.5, 0.2])
    points = stream_of(stream, [(target, np.zeros(6))] * 25)
    stream.hold()
    points.append(stream.next())
    assert stream.at_rest and all(len(value) == 6 for point in points for value in point)
    np.testing.assert_allclose(points[-1].position, target, atol=1e-9)
    velocity = np.array([point.velocity for point in points])
    ratios = limit_ratios(velocity, np.array([point.acceleration for point in points]), TIMING.servo_period, limits)
    for name, ratio in ratios.items():
        assert ratio.shape == (6,) and np.all(ratio <= 1 + 1e-9), (name, ratio)
    # Joint 5's 0.5 rad step, asked for within 20 ms, speeds up at its 10 rad/s² limit (the Panda's joint 5: 15).
    assert ratios["acceleration"][4] > 0.99
