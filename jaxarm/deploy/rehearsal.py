"""A real-time rehearsal: one episode of a policy through the deployment loop on stock MuJoCo in a process of its
own (`driver.serve`), behind a socket, in wall-clock time (`remote.RemoteRobot`). Imports numpy, mujoco, zmq and
ruckig alone.
"""

import dataclasses
import multiprocessing
import signal
from collections.abc import Callable
from multiprocessing.process import BaseProcess

import numpy as np

from jaxarm.deploy import wire
from jaxarm.deploy.driver import DriverSetup, serve
from jaxarm.deploy.loop import DeploymentLoop
from jaxarm.deploy.remote import Fault, RemoteRobot, RobotStopped


@dataclasses.dataclass(frozen=True)
class Rehearsal:
    """One rehearsed episode.

    Attributes:
      steps: the policy's ticks.
      jitter: [steps] seconds each tick after the first started after its slot.
      deadline_misses: commands the policy sent later than the latency budget after their tick's start.
      fault: why the robot held (`wire.FAULTS`): "ended" where the policy's run ended it.
      final: the robot's last state, at rest.
      stream: the robot's `driver.StreamLog`, as arrays by field.
    """

    steps: int
    jitter: np.ndarray
    deadline_misses: int
    fault: str
    final: wire.State
    stream: dict[str, np.ndarray]


def start_driver(setup: DriverSetup) -> BaseProcess:
    """The robot process, started: spawned, so that it runs none of its parent's state (JAX, threads), and deaf to
    Ctrl-C, which reaches every process of the terminal's group: it reacts to its policy's end as to any command
    that does not come, holding and stopping (a Ctrl-C that ended it mid-stream printed its KeyboardInterrupt
    traceback beside the rehearsal's one line)."""
    process = multiprocessing.get_context("spawn").Process(target=serve, args=(setup,), name="robot")
    ignored = signal.signal(signal.SIGINT, signal.SIG_IGN)  # inherited by the spawned interpreter from its start
    try:
        process.start()
    finally:
        signal.signal(signal.SIGINT, ignored)
    return process


def drive(loop: DeploymentLoop, robot: RemoteRobot, ctrl: np.ndarray, steps: int, done: Callable[[], bool]) -> int:
    """Runs `loop` on `robot` from the servo targets `ctrl` [J + F] (`loop`) for up to `steps` ticks, until `done()`
    or the robot stops; returns the ticks run."""
    robot.connect(ctrl)
    loop.begin(ctrl)
    ticks = 0
    try:
        while ticks < steps and not done():
            loop.drive(robot, robot.estimate())
            ticks += 1
    except RobotStopped:
        pass
    return ticks


def rehearse(
    loop: DeploymentLoop,
    setup: DriverSetup,
    object_shape: np.ndarray,
    object_size: np.ndarray,
    steps: int,
    done: Callable[[], bool],
    fault: Fault | None = None,
) -> Rehearsal:
    """One episode of `loop` on the robot process `setup` describes (objects of `object_shape` and `object_size`
    [N]) for up to `steps` ticks, until `done()`, with `fault` injected; ends the policy's run and waits for the robot
    to hold and stop."""
    process = start_driver(setup)
    robot = RemoteRobot(setup.address, setup.timing, object_shape, object_size, fault)
    try:
        ticks = drive(loop, robot, setup.ctrl, steps, done)
        final = robot.end()
    finally:
        robot.close()
        process.join(setup.timing.connect_timeout)
        if process.is_alive():
            process.kill()
    with np.load(setup.log_path) as stream:
        arrays = dict(stream)
    fault_name = wire.FAULTS[int(arrays["fault"])]
    return Rehearsal(ticks, np.array(robot.schedule.jitter), robot.deadline_misses, fault_name, final, arrays)
