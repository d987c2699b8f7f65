"""Thin adapters from the deployment loop's `loop.Robot` to robots' own Python drivers: a Panda through
franky-control, a UR5e through ur_rtde (the adapters extra). Typed against the APIs those packages publish
(franky-control 2.0's stubs, ur_rtde 1.6's documentation) by the protocols below, and tested against stand-ins of
them only: **neither has run on hardware here.** Imports numpy alone; a driver's package is imported when an adapter
connects.

Each driver streams to its arm at the arm's servo rate itself (franky: Ruckig at 1 kHz within Franka's limits, as
`stream.ServoStream` does in the rehearsal; ur_rtde: servoJ with the controller's lookahead filter). An adapter hands
it each control tick's targets, keeps the policy's wall-clock schedule (`clock.Schedule`), and `hold` brakes the arm
to rest and stops: the rehearsal's safe reaction, called by whoever runs the loop when a tick fails. J is the arm's
joint count; servo targets `ctrl` are the J arm joints' then the fingers' (`loop`).
"""

import importlib
import time
from typing import Any, Protocol

import numpy as np

from jaxarm.deploy.clock import Schedule
from jaxarm.deploy.reading import ArmReading
from jaxarm.robots import PANDA, UR5E, RobotDescription

GRIPPER_SPEED = 0.1
"""Franka Hand's finger speed for a new width (m/s; its maximum is about 0.1)."""
GRIPPER_DEADBAND = 0.005
"""A new gripper width (m) is sent only when it differs this much from the last: the Hand takes one command at a
time and is slow, so a width that moves by noise every tick would queue commands behind each other."""


class FrankyJointState(Protocol):
    """`franky.JointState`: joint positions and velocities [J]."""

    @property
    def position(self) -> np.ndarray: ...

    @property
    def velocity(self) -> np.ndarray: ...


class FrankyArm(Protocol):
    """The part of `franky.Robot` the adapter uses."""

    @property
    def current_joint_state(self) -> FrankyJointState: ...

    def move(self, motion: Any, asynchronous: bool = False) -> None: ...

    def join_motion(self, timeout: float | None = None) -> bool: ...


class FrankyGripper(Protocol):
    """The part of `franky.Gripper` the adapter uses."""

    @property
    def width(self) -> float: ...

    def move_async(self, width: float, speed: float) -> Any: ...


class FrankyRobot:
    """A Panda through franky-control, as a `loop.Robot`: each tick's arm targets become a `franky.JointMotion` to that
    position, arriving at the loop's rate over the tick, which replaces the running one (franky's real-time motion
    update); the fingers' targets become a width for the Hand.

    Franka-only, as franky is: `description` is the Panda's by default and another Franka arm's at most (franky
    drives no other); the adapter still reads J from it, as every other part of the loop does.

    Args:
      arm, gripper: a connected `franky.Robot` and `franky.Gripper` (`connect` makes them).
      franky: the franky module (its motion and state classes).
      control_period: seconds per control tick.
      description: the arm's description (its joint count).
    """

    def __init__(
        self,
        arm: FrankyArm,
        gripper: FrankyGripper,
        franky: Any,
        control_period: float,
        description: RobotDescription = PANDA,
    ):
        self.arm, self.gripper, self.franky = arm, gripper, franky
        self.joints = len(description.arm_joints)
        self.schedule = Schedule(control_period)
        self._targets: np.ndarray | None = None
        self._width: float | None = None

    @classmethod
    def connect(cls, host: str, control_period: float, dynamics_factor: float = 1.0) -> "FrankyRobot":
        """The Panda at `host` (its FCI address), errors recovered, with franky's limits at `dynamics_factor` of
        Franka's (1: the loop's targets are already within the datasheet's speed and acceleration limits; less slows
        every motion, for first trials)."""
        franky = importlib.import_module("franky")
        arm = franky.Robot(host, relative_dynamics_factor=dynamics_factor)
        arm.recover_from_errors()
        return cls(arm, franky.Gripper(host), franky, control_period)

    def now(self) -> float:
        return time.monotonic()

    def reading(self) -> ArmReading:
        state = self.arm.current_joint_state
        # The Hand reports its width alone; the env's fingers open symmetrically, each by half.
        finger_q = np.full(2, self.gripper.width / 2)
        return ArmReading(np.asarray(state.position, np.float64), np.asarray(state.velocity, np.float64), finger_q)

    def command(self, ctrl: np.ndarray) -> None:
        """Sends servo targets [J + 2]: the arm's to franky, the fingers' as the Hand's width; starts the schedule at
        the first."""
        arm = np.asarray(ctrl[: self.joints], np.float64)
        if self._targets is None:
            self.schedule.start()
            velocity = np.zeros(self.joints)
        else:
            velocity = (arm - self._targets) / self.schedule.period
        self._targets = arm
        target = self.franky.JointState(position=arm, velocity=velocity)
        self.arm.move(self.franky.JointMotion(target), asynchronous=True)
        width = float(np.sum(ctrl[self.joints :]))
        if self._width is None or abs(width - self._width) >= GRIPPER_DEADBAND:
            self.gripper.move_async(width, GRIPPER_SPEED)
            self._width = width

    def step(self) -> None:
        self.schedule.wait()

    def hold(self) -> None:
        """Brakes the arm to rest within franky's limits and waits until it is still; the gripper keeps its grip."""
        self.arm.move(self.franky.JointStopMotion(), asynchronous=True)
        self.arm.join_motion()


class RtdeControl(Protocol):
    """The part of `rtde_control.RTDEControlInterface` the adapter uses (ur_rtde's camelCase names)."""

    def servoJ(
        self, q: list[float], speed: float, acceleration: float, time: float, lookahead_time: float, gain: float
    ) -> bool: ...

    def servoStop(self, a: float = 10.0) -> bool: ...

    def stopScript(self) -> None: ...


class RtdeReceive(Protocol):
    """The part of `rtde_receive.RTDEReceiveInterface` the adapter uses."""

    def getActualQ(self) -> list[float]: ...

    def getActualQd(self) -> list[float]: ...


class RtdeRobot:
    """A UR5e through ur_rtde, as a `loop.Robot` of its 6 joints and no gripper (its readings' `finger_q` is empty):
    each tick's targets go to servoJ, whose lookahead filter smooths them over the control period. A task built on
    the UR5e (`env_kwargs.robot=ur5e`, `jaxarm.robots.UR5E`) sends its 6 joint targets, then the fingers', which no
    gripper driver here receives.

    Args:
      control, receive: connected `rtde_control.RTDEControlInterface` and `rtde_receive.RTDEReceiveInterface`.
      control_period: seconds per control tick (servoJ's `time`).
      lookahead_time: servoJ's smoothing horizon (s, 0.03-0.2).
      gain: servoJ's proportional gain (100-2000).
    """

    JOINTS = len(UR5E.arm_joints)

    def __init__(
        self,
        control: RtdeControl,
        receive: RtdeReceive,
        control_period: float,
        lookahead_time: float = 0.1,
        gain: float = 300.0,
    ):
        self.control, self.receive = control, receive
        self.schedule = Schedule(control_period)
        self.lookahead_time, self.gain = lookahead_time, gain
        self._started = False

    @classmethod
    def connect(cls, host: str, control_period: float) -> "RtdeRobot":
        """The UR at `host`, its control script started by ur_rtde."""
        control = importlib.import_module("rtde_control").RTDEControlInterface(host)
        receive = importlib.import_module("rtde_receive").RTDEReceiveInterface(host)
        return cls(control, receive, control_period)

    def now(self) -> float:
        return time.monotonic()

    def reading(self) -> ArmReading:
        q, qd = self.receive.getActualQ(), self.receive.getActualQd()
        return ArmReading(np.asarray(q, np.float64), np.asarray(qd, np.float64), np.zeros(0))

    def command(self, ctrl: np.ndarray) -> None:
        """Sends the arm's joint targets (the first `JOINTS` of `ctrl`; the fingers' are ignored); starts the schedule
        at the first."""
        if not self._started:
            self.schedule.start()
            self._started = True
        # servoJ's speed and acceleration are unused by the controller (UR's script manual): 0 for both.
        target = [float(q) for q in ctrl[: self.JOINTS]]
        self.control.servoJ(target, 0.0, 0.0, self.schedule.period, self.lookahead_time, self.gain)

    def step(self) -> None:
        self.schedule.wait()

    def hold(self) -> None:
        """Brakes the arm to rest (servoStop's deceleration) and ends ur_rtde's control script."""
        self.control.servoStop()
        self.control.stopScript()
