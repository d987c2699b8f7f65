"""The real-time rehearsal on the CPU: stock MuJoCo as the robot in its own process behind a socket, a 25 Hz loop
swaying the arm through the jerk-limited 1 kHz stream, and each fault (a late, a dropped, a stalled command, the
policy's process killed) ending in hold-then-stop with every setpoint within Franka's limits. Each runs for about
a second of wall clock, most of it the robot process's start. And the robot's watchdog and messages alone."""

import multiprocessing
import os
import signal
import time

import mujoco
import numpy as np
import pytest

from jaxarm.deploy import wire
from jaxarm.deploy.driver import DriverSetup, judge
from jaxarm.deploy.reading import ArmReading
from jaxarm.deploy.rehearsal import Rehearsal, rehearse, start_driver
from jaxarm.deploy.remote import Fault
from jaxarm.deploy.stream import limit_ratios
from jaxarm.envs.panda_sort import model as sort_model
from jaxarm.envs.panda_sort.layout import make_layout
from tests.deploy.sway import TIMING, run_policy, sway_loop

STEPS = 15
"""Policy ticks of a rehearsal: 0.6 s."""
FAULT_TICK = 8


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(the .mjb path, qpos, ctrl [9]): the sorter's scene with two objects, the arm at rest in its start posture."""
    model = sort_model.build_model(2, make_layout())
    path = tmp_path_factory.mktemp("scene") / "robot.mjb"
    mujoco.mj_saveModel(model, str(path))
    data = mujoco.MjData(model)
    start = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.8])
    data.qpos[:7] = start
    return str(path), data.qpos.copy(), np.concatenate([start, [0.04, 0.04]])


def test_the_watchdog_names_each_fault():
    # The command after the last one followed: due one control period after its tick, within the latency budget.
    last = wire.Command(wire.TARGET, 4, 1.0 - TIMING.control_period, np.zeros(9))
    on_time = wire.Command(wire.TARGET, 5, 1.0, np.zeros(9))
    assert judge(on_time, 1.0 + TIMING.latency_budget - 1e-3, last, TIMING) == wire.NO_FAULT
    assert judge(on_time, 1.0 + TIMING.latency_budget + 1e-3, last, TIMING) == wire.MISSED
    assert judge(on_time._replace(seq=6), 1.0, last, TIMING) == wire.DROPPED
    assert judge(on_time._replace(ctrl=np.full(9, np.nan)), 1.0, last, TIMING) == wire.UNSAFE
    assert judge(on_time._replace(kind=wire.END), 9.0, last, TIMING) == wire.ENDED


def test_messages_round_trip():
    command = wire.Command(wire.TARGET, 7, 12.5, np.arange(9.0))
    decoded = wire.decode_command(wire.encode_command(command))
    assert decoded[:3] == command[:3]
    np.testing.assert_array_equal(decoded.ctrl, command.ctrl)
    # A Panda's reading, and a 6-joint arm's without a gripper: a state carries its own joint and finger counts.
    for joints, finger_q in [(7, np.array([0.01, 0.02])), (6, np.zeros(0))]:
        reading = ArmReading(np.arange(joints, dtype=float), -np.arange(joints, dtype=float), finger_q)
        state = wire.State(wire.HOLDING, wire.MISSED, 3.0, reading, np.ones((2, 7)), np.zeros((2, 6)))
        decoded_state = wire.decode_state(wire.encode_state(state))
        assert decoded_state[:3] == state[:3]
        for ours, theirs in zip((*decoded_state.reading, *decoded_state[4:]), (*reading, *state[4:]), strict=True):
            np.testing.assert_array_equal(ours, theirs)


def driver_setup(scene, tmp_path) -> DriverSetup:
    path, qpos, ctrl = scene
    no_objects = np.zeros((0, 7), np.int64), np.zeros((0, 6), np.int64)
    address = f"ipc://{tmp_path}/robot.ipc"
    return DriverSetup(address, path, qpos, ctrl, *no_objects, TIMING, str(tmp_path / "stream.npz"))


ATTEMPTS = 3
"""Rehearsals of a case before its test judges the last: a shared 2-core CI host can stall a process past even the
tests' budget, which the watchdog rightly calls a miss. A rehearsal held by a miss before its injected fault's tick
was the machine's, not the code's, and runs again; any other outcome is judged as it is."""


def stalled_by_the_host(result: Rehearsal, fault: Fault | None) -> bool:
    return result.fault == "missed" and result.steps < (STEPS if fault is None else fault.tick)


def sway(setup: DriverSetup, fault: Fault | None = None) -> Rehearsal:
    for _ in range(ATTEMPTS):
        result = rehearse(sway_loop(setup), setup, np.zeros(0, int), np.zeros(0), STEPS, lambda: False, fault)
        if not stalled_by_the_host(result, fault):
            break
    return result


def assert_held_then_stopped_within_the_limits(stream: dict[str, np.ndarray]) -> None:
    hold, stop = int(stream["hold_tick"]), int(stream["stop_tick"])
    assert 0 <= hold < stop == len(stream["position"]) - 1
    np.testing.assert_allclose(stream["velocity"][-1], 0.0, atol=1e-9)
    np.testing.assert_allclose(stream["acceleration"][-1], 0.0, atol=1e-9)
    for name, ratio in limit_ratios(stream["velocity"], stream["acceleration"], TIMING.servo_period).items():
        assert np.all(ratio <= 1 + 1e-6), (name, ratio)
    # The positions sent are the stream's own: each moved by the setpoints' speed, within the speed limit.
    steps = np.abs(np.diff(stream["position"], axis=0)) / TIMING.servo_period
    assert np.all(limit_ratios(steps, stream["acceleration"], TIMING.servo_period)["speed"] <= 1 + 1e-3)


def test_a_rehearsal_that_ends_holds_then_stops_where_the_arm_is(scene, tmp_path):
    result = sway(driver_setup(scene, tmp_path))
    assert result.fault == "ended" and result.steps == STEPS and result.final.status == wire.STOPPED
    assert_held_then_stopped_within_the_limits(result.stream)
    # The stream swayed the arm, and the policy kept its 25 Hz ticks.
    assert np.ptp(result.stream["position"][:, 0]) > 0.1 and np.ptp(result.final.reading.arm_q) > 0.1
    assert len(result.jitter) == STEPS and np.median(result.jitter) < 0.01


@pytest.mark.parametrize(("kind", "fault"), [("late", "missed"), ("drop", "dropped"), ("stall", "missed")])
def test_each_fault_ends_in_hold_then_stop(scene, tmp_path, kind, fault):
    result = sway(driver_setup(scene, tmp_path), Fault(kind, FAULT_TICK))
    assert result.fault == fault and result.steps < STEPS
    assert_held_then_stopped_within_the_limits(result.stream)
    # It held when the next command showed the gap (tick 9's), or at the deadline after the last command on time
    # (tick 7's: one control period and the budget after it), on the robot's wall clock from its start.
    hold = int(result.stream["hold_tick"])
    held = hold * TIMING.servo_period + result.stream["lateness"][hold]
    due = (FAULT_TICK + 1) * TIMING.control_period if kind == "drop" else FAULT_TICK * 0.04 + TIMING.latency_budget
    assert due <= held < due + 0.1


def test_a_killed_policy_process_ends_in_hold_then_stop(scene, tmp_path):
    setup = driver_setup(scene, tmp_path)
    context = multiprocessing.get_context("spawn")
    running = context.Event()
    driver = start_driver(setup)
    policy = context.Process(target=run_policy, args=(setup, running))
    policy.start()
    try:
        assert running.wait(30)
        time.sleep(0.2)
        os.kill(policy.pid, signal.SIGKILL)
        driver.join(10)
    finally:
        for process in (policy, driver):
            if process.is_alive():
                process.kill()
    with np.load(setup.log_path) as stream:
        assert wire.FAULTS[int(stream["fault"])] == "missed"
        assert_held_then_stopped_within_the_limits(dict(stream))
