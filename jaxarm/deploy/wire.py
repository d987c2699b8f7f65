"""The messages between a policy process and a robot process (`remote.RemoteRobot`, `driver.serve`), and the
deadlines both keep: flat float64 arrays, one per zmq message, so that each side reads them with numpy alone and
nothing on the wire is executable. Imports numpy and zmq alone.

A command: [kind, seq, stamp, ctrl 9]; `seq` counts the policy's commands from 0 (a gap is a dropped one); `stamp`
is the time (s, the host's monotonic clock, which both processes of a rehearsal share) of the control tick it was
computed for. A state: [status, fault, time, arm_q 7, arm_qvel 7,
finger_q 2, object pose N×7, object velocity N×6]: the robot's reading and what an object detector would report,
with the robot's status and the fault that made it hold.
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
ARM_FIELDS = 3 + 7 + 7 + 2


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
    """A policy's command: its `kind` (`TARGET`, `END`), number, its tick's stamp (s) and servo targets [9]."""

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
    head = [state.status, state.fault, state.time]
    parts = [head, reading.arm_q, reading.arm_qvel, reading.finger_q, state.object_pose.ravel()]
    return np.concatenate([*parts, state.object_velocity.ravel()]).astype(np.float64).tobytes()


def decode_state(message: bytes) -> State:
    values = np.frombuffer(message, np.float64)
    count = (len(values) - ARM_FIELDS) // 13
    pose_end = ARM_FIELDS + 7 * count
    return State(
        status=int(values[0]),
        fault=int(values[1]),
        time=float(values[2]),
        reading=ArmReading(values[3:10].copy(), values[10:17].copy(), values[17:19].copy()),
        object_pose=values[ARM_FIELDS:pose_end].reshape(count, 7).copy(),
        object_velocity=values[pose_end:].reshape(count, 6).copy(),
    )


def send(socket: zmq.Socket, message: bytes) -> None:
    """Sends without blocking; a message the other side has no room for (it is gone, or stalled) is dropped, as a
    lost packet would be: its deadlines are the other side's to keep."""
    with contextlib.suppress(zmq.Again):
        socket.send(message, zmq.NOBLOCK)
