"""The messages between a policy process and a robot process (`remote.RemoteRobot`, `driver.serve`), and the
deadlines both keep: flat float64 arrays, one per zmq message, so that each side reads them with numpy alone and
nothing on the wire is executable. Imports numpy and zmq alone.

J and F are the arm's joint and finger counts. A command: [kind, seq, stamp, ctrl J + F]; `seq` counts the policy's
commands from 0 (a gap is a dropped one); `stamp` is the time (s, the host's monotonic clock, which both processes of
a rehearsal share) of the control tick it was computed for. A state: [status, fault, time, J, F, arm_q J, arm_qvel J,
finger_q F, object pose N×7, object velocity N×6]: the robot's reading and what an object detector would report,
with the robot's status and the fault that made it hold; it carries its own J and F, so that either side reads any
arm's.
"""

import contextlib
import dataclasses
from typing import NamedTuple

import numpy as np
import zmq

from jaxarm.deploy.reading import ArmReading

TARGET, END = 0, 1
"""A command's kinds: servo targets, or the end of the policy's run (the robot holds, then stops)."""
RUNNING, HOLDING, STOPPED = 0, 1, 2
"""A robot's statuses: following targets; braking to rest after a fault; at rest, taking no more commands."""
NO_FAULT, ENDED, DROPPED, MISSED, UNSAFE = range(5)
FAULTS = ("none", "ended", "dropped", "missed", "unsafe")
"""Why a robot held, by the code a state carries: no fault; the policy's END; a gap in the commands' numbers; no
command by its deadline (a late or stalled one, or a policy process that died: the robot cannot tell which before
the deadline passes); servo targets that are not finite."""
STATE_HEAD = 5
"""A state's fields before the reading: status, fault, time, J, F."""


@dataclasses.dataclass(frozen=True)
class Timing:
    """The clocks and deadlines both processes of a rehearsal keep.

    Attributes:
      servo_period: seconds between the robot's setpoints and physics steps (Franka's 1 kHz).
      control_period: seconds between the policy's ticks (the envs' 25 Hz control step).
      latency_budget: how long after its tick's start a command may arrive: the policy's observation, network and
        IK (2 ms at p99 on one core, BENCHMARKS.md) with room for a loaded host's scheduling.
      publish_period: seconds between the robot's states (the policy reads the newest at each tick).
      connect_timeout: seconds the robot waits for the policy's first command before it gives up.
    """

    servo_period: float = 0.001
    control_period: float = 0.04
    latency_budget: float = 0.02
    publish_period: float = 0.01
    connect_timeout: float = 20.0

    @property
    def deadline(self) -> float:
        """Seconds after a command's stamp by which the next command must arrive: one control period, and the
        latency budget."""
        return self.control_period + self.latency_budget

    @property
    def arrival(self) -> float:
        """Seconds after a target is given that the servo stream reaches it (at the earliest): half a control
        period, where on average the envs' servos, whose targets step once a tick, lag the path the targets trace."""
        return self.control_period / 2

    @property
    def publish_every(self) -> int:
        """Servo ticks between the robot's states."""
        return round(self.publish_period / self.servo_period)


class Command(NamedTuple):
    """A policy's command: its `kind` (`TARGET`, `END`), number, its tick's stamp (s) and servo targets [J + F]
    (none for `END`)."""

    kind: int
    seq: int
    stamp: float
    ctrl: np.ndarray


class State(NamedTuple):
    """A robot's state: status, fault code (an index of `FAULTS`), its clock (s), its reading, and its objects'
    poses [N, 7] and velocities [N, 6]."""

    status: int
    fault: int
    time: float
    reading: ArmReading
    object_pose: np.ndarray
    object_velocity: np.ndarray


def encode_command(command: Command) -> bytes:
    return np.concatenate([[command.kind, command.seq, command.stamp], command.ctrl]).astype(np.float64).tobytes()


def decode_command(message: bytes) -> Command:
    values = np.frombuffer(message, np.float64)
    return Command(int(values[0]), int(values[1]), float(values[2]), values[3:].copy())


def encode_state(state: State) -> bytes:
    reading = state.reading
    head = [state.status, state.fault, state.time, len(reading.arm_q), len(reading.finger_q)]
    parts = [head, reading.arm_q, reading.arm_qvel, reading.finger_q, state.object_pose.ravel()]
    return np.concatenate([*parts, state.object_velocity.ravel()]).astype(np.float64).tobytes()


def decode_state(message: bytes) -> State:
    values = np.frombuffer(message, np.float64)
    joints, fingers = int(values[3]), int(values[4])
    count = (len(values) - STATE_HEAD - 2 * joints - fingers) // 13
    sizes = np.cumsum([joints, joints, fingers, 7 * count])
    arm_q, arm_qvel, finger_q, pose, velocity = np.split(values[STATE_HEAD:].copy(), sizes)
    return State(
        status=int(values[0]),
        fault=int(values[1]),
        time=float(values[2]),
        reading=ArmReading(arm_q, arm_qvel, finger_q),
        object_pose=pose.reshape(count, 7),
        object_velocity=velocity.reshape(count, 6),
    )


def send(socket: zmq.Socket, message: bytes) -> None:
    """Sends without blocking; a message the other side has no room for (it is gone, or stalled) is dropped, as a
    lost packet would be: its deadlines are the other side's to keep."""
    with contextlib.suppress(zmq.Again):
        socket.send(message, zmq.NOBLOCK)
