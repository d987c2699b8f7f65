"""The deployment loop: each control tick, a robot's reading -> the env's observation -> the exported policy ->
the env's controller -> servo targets within the arm's limits, timed. Imports numpy and mujoco alone.

Servo targets (`ctrl`, [J + F]) are the J arm joints' targets (rad) then the F fingers' openings (m), J and F the
lengths of the robot description's `arm_joints` and `finger_joints` (the Panda's 7 and 2 by default).

The limits are the envs' own (`ArmBase.limited_ctrl` applies `limits.limit_targets` to the same targets), so with
`clip` the robot gets the targets the env's servos got, and the counts tell how often the policy asked for more.
A policy's action that is not finite is refused (`UnsafeAction`): nothing is sent, and the robot stops at the last
targets it was sent."""

import dataclasses
import time
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.limits import limit_targets
from jaxarm.deploy.reading import ArmReading
from jaxarm.robots import PANDA, RobotDescription


class UnsafeAction(RuntimeError):
    """The policy gave an action that is not finite (NaN or infinite), which no servo target may be made of: the
    loop sent nothing, so the robot holds the last targets it was sent (finite, within the arm's limits) and stops
    there. The message says at which tick and what the action was, in one line."""


class Task(Protocol):
    """A task's numbers (`sort.SortTask`, `peg.PegTask`): a frozen dataclass of plain numbers and arrays, which
    `files.save` writes field by field."""

    @property
    def start_qpos(self) -> np.ndarray: ...


class Controller(Protocol):
    """A task's observation and control at a robot (`sort.SortController`, `peg.PegController`)."""

    @property
    def task(self) -> Task: ...

    @property
    def kinematics(self) -> ArmKinematics: ...

    @property
    def action_size(self) -> int: ...

    def begin(self) -> None: ...

    def observe(self, reading: ArmReading, estimate: Any, ctrl: np.ndarray) -> Any:
        """The policy's observation: a flat float32 [O], or a camera policy's parts by name
        (`camera.CameraController`)."""
        ...

    def act(self, reading: ArmReading, ctrl: np.ndarray, action: np.ndarray) -> np.ndarray: ...


class Robot(Protocol):
    """A robot as the loop drives it, one control tick at a time: stock MuJoCo (`mujoco_robot.MujocoRobot`), a robot
    process behind a socket (`remote.RemoteRobot`), or a robot's own driver (`adapters`)."""

    def now(self) -> float:
        """Seconds on the robot's clock: simulated time for a simulator, wall-clock time for a real robot."""
        ...

    def reading(self) -> ArmReading:
        """What the arm's sensors report now."""
        ...

    def command(self, ctrl: np.ndarray) -> None:
        """Sends servo targets [J + F]: the arm's joints (rad), then each finger's opening (m)."""
        ...

    def step(self) -> None:
        """Lets one control period pass on the robot's clock: a simulator steps its physics, a real robot's loop
        waits for its next tick."""
        ...


@dataclasses.dataclass
class LimitCounts:
    """How often the loop's commands went beyond the arm's limits, per arm joint, over the ticks so far.

    Attributes:
      acceleration: [J] ticks at which a joint's asked rate changed faster than its acceleration limit.
      speed: [J] ticks at which a joint's rate (after the acceleration limit) was beyond its speed limit.
    """

    acceleration: np.ndarray
    speed: np.ndarray


class DeploymentLoop:
    """Runs a policy on a robot one control tick at a time.

    Args:
      policy: the controller's observation (flat [O], or a camera's parts) -> action [A]
        (`jaxarm.export.numpy_policy.load(path)`).
      controller: the task's observation and control.
      period: seconds per tick (the env's control step).
      clip: whether commands beyond the arm's limits are clipped (else only counted).
      description: the robot's description (the Panda's by default): its joint and finger counts and its limits.

    Attributes:
      joints: J, the arm's joint count.
      ctrl: [J + F] the last servo targets sent (arm, fingers).
      counts: the limits' clips so far (`LimitCounts`).
      tick_seconds: wall time of each tick so far (observation, policy, control, limits).
    """

    def __init__(
        self,
        policy: Callable[[Any], np.ndarray],
        controller: Controller,
        period: float,
        clip: bool = True,
        description: RobotDescription = PANDA,
    ):
        self.policy = policy
        self.controller = controller
        self.period = period
        self.clip = clip
        self.joints = len(description.arm_joints)
        self._limits = description.joint_limits
        self.ctrl = np.zeros(self.joints + len(description.finger_joints))
        self._velocity = np.zeros(self.joints)
        self.counts = LimitCounts(acceleration=np.zeros(self.joints, np.int64), speed=np.zeros(self.joints, np.int64))
        self.tick_seconds: list[float] = []

    def begin(self, ctrl: np.ndarray) -> None:
        """A new episode with the servos at `ctrl` [J + F] and the arm at rest."""
        self.ctrl = np.array(ctrl, np.float64)
        self._velocity = np.zeros(self.joints)
        self.controller.begin()

    def tick(self, reading: ArmReading, estimate: Any) -> np.ndarray:
        """[J + F] the servo targets to send for this tick's `reading` and the task's `estimate`; `UnsafeAction`, with
        nothing to send (the robot stops at its last targets, `ctrl`), where the policy's action is not finite."""
        start = time.perf_counter()
        obs = self.controller.observe(reading, estimate, self.ctrl)
        action = np.asarray(self.policy(obs), np.float64)
        if not np.all(np.isfinite(action)):
            # Checked before the controller: its clips and gripper thresholds could turn NaN into a finite target.
            # The robot comes to rest at its last targets: a later tick's limits start from rest.
            self._velocity = np.zeros(self.joints)
            raise UnsafeAction(
                f"the policy's action at tick {len(self.tick_seconds) + 1} is not finite "
                f"({np.array2string(action, precision=3, separator=', ')}); the robot was stopped at its last targets"
            )
        ctrl = self.controller.act(reading, self.ctrl, action)
        arm = slice(self.joints)
        limited = limit_targets(ctrl[arm], self.ctrl[arm], self._velocity, self.period, self._limits)
        self.counts.acceleration += limited.acceleration_clipped
        self.counts.speed += limited.speed_clipped
        if self.clip:
            ctrl[arm] = limited.targets
            self._velocity = limited.velocity
        else:
            self._velocity = (ctrl[arm] - self.ctrl[arm]) / self.period
        self.ctrl = ctrl
        self.tick_seconds.append(time.perf_counter() - start)
        return ctrl

    def drive(self, robot: Robot, estimate: Any) -> np.ndarray:
        """One control tick on `robot`: its reading -> `tick` -> the targets sent to it (returned, [J + F]), then one
        control period on its clock."""
        ctrl = self.tick(robot.reading(), estimate)
        robot.command(ctrl)
        robot.step()
        return ctrl
