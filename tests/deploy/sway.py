"""A 25 Hz loop that sways the arm, for the rehearsal's tests: imports no JAX, so that a policy process spawned
with it starts in a fraction of a second."""

import numpy as np

from jaxarm.deploy import wire
from jaxarm.deploy.driver import DriverSetup
from jaxarm.deploy.loop import DeploymentLoop
from jaxarm.deploy.rehearsal import drive
from jaxarm.deploy.remote import RemoteRobot

TIMING = wire.Timing(latency_budget=0.06)
"""A budget of 60 ms, not 20: CI's 2 cores, shared with another test worker compiling MJX programs, delay a tick by
tens of milliseconds at times (20 ms tripped the watchdog in 1 of 3 runs at load 16 here), and the faults still miss
it: a late command comes 90 ms after its tick, a stalled one 100 ms."""


class SwayController:
    """Sways every arm joint about its start by 0.2 rad at 1 Hz, the gripper open (the policy's action unused)."""

    action_size = 1

    def __init__(self, start_qpos: np.ndarray):
        self.start_qpos = start_qpos
        self.ticks = 0

    def begin(self) -> None:
        self.ticks = 0

    def observe(self, reading, estimate, ctrl):
        return np.zeros(1, np.float32)

    def act(self, reading, ctrl, action):
        self.ticks += 1
        sway = 0.2 * np.sin(2 * np.pi * self.ticks * TIMING.control_period)
        return np.concatenate([self.start_qpos + sway, [0.04, 0.04]])


def sway_loop(setup: DriverSetup) -> DeploymentLoop:
    """A loop that sways the arm of `setup`'s scene from its start targets (the policy's action unused)."""
    return DeploymentLoop(lambda obs: np.zeros(1), SwayController(setup.ctrl[:7]), TIMING.control_period)


def run_policy(setup: DriverSetup, running) -> None:
    """The policy's process: sways the arm for a long run (killed before its end), `running` set once it drives."""

    def started() -> bool:
        running.set()
        return False

    robot = RemoteRobot(setup.address, TIMING, np.zeros(0, int), np.zeros(0))
    drive(sway_loop(setup), robot, setup.ctrl, 1000, started)
