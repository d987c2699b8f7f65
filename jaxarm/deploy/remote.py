"""The policy's side of a real-time rehearsal: a robot process behind a zmq socket (`driver.serve`) as a `loop.Robot`
on the policy's own wall-clock schedule, with its ticks' jitter and deadline misses counted and faults injected on
request. Imports numpy and zmq alone. Servo targets `ctrl` [J + F] are the J arm joints' then the F fingers'
(`loop`).
"""

import dataclasses
import time

import numpy as np
import zmq

from jaxarm.deploy import wire
from jaxarm.deploy.clock import Schedule
from jaxarm.deploy.reading import ArmReading, ObjectEstimate

FAULT_KINDS = ("late", "drop", "stall")
"""Faults the policy's side injects at one tick: its command sent late (1.5 latency budgets after the tick's start),
not sent, or sent after a 100 ms stall. A killed policy process is the fourth, from outside (tests/deploy)."""
STALL_SECONDS = 0.1


@dataclasses.dataclass(frozen=True)
class Fault:
    """One of `FAULT_KINDS` at the policy's tick `tick` (0-based)."""

    kind: str
    tick: int

    def __post_init__(self):
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"fault {self.kind!r} is none of {', '.join(FAULT_KINDS)}")
        if self.tick < 0:  # a tick no episode reaches: the rehearsal reported no fault, as if it had none
            raise ValueError(f"a fault's tick counts the policy's ticks from 0, got {self.tick}")


class RobotStopped(RuntimeError):
    """The robot held and stopped (its fault in the message), or sent no state for a deadline: the policy's run is
    over."""


class RemoteRobot:
    """A robot process at `address`, driven at `timing.control_period` on the wall clock (a `loop.Robot`).

    Its ticks keep `schedule` from `connect` on; each command is stamped with its tick's start.

    Args:
      address: the robot process's zmq address.
      timing: the rehearsal's clocks and deadlines, as the robot process keeps them.
      object_shape, object_size: [N] the objects' shapes and sizes (fixed over an episode; the robot's states carry
        their poses and velocities).
      fault: a fault to inject, or None.

    Attributes:
      state: the newest state the robot sent.
      schedule: the policy's ticks, and each one's jitter.
      deadline_misses: commands sent later than the latency budget after their tick's start.
    """

    def __init__(
        self,
        address: str,
        timing: wire.Timing,
        object_shape: np.ndarray,
        object_size: np.ndarray,
        fault: Fault | None = None,
    ):
        self.timing = timing
        self.object_shape, self.object_size = object_shape, object_size
        self.fault = fault
        self.schedule = Schedule(timing.control_period)
        self.deadline_misses = 0
        self._seq = 0
        self._context = zmq.Context()
        self._socket = self._context.socket(zmq.PAIR)
        self._socket.connect(address)

    def connect(self, ctrl: np.ndarray) -> None:
        """Starts the robot's clock with the servo targets it starts at (`ctrl` [J + F]), and the policy's schedule at
        the robot's first state; `RobotStopped` if none comes within the connect timeout."""
        self._socket.send(wire.encode_command(wire.Command(wire.TARGET, 0, time.monotonic(), ctrl)))
        if not self._socket.poll(round(self.timing.connect_timeout * 1000)):
            raise RobotStopped(f"no state from the robot within {self.timing.connect_timeout} s")
        self.state = wire.decode_state(self._socket.recv())
        self.schedule.start()

    def now(self) -> float:
        return time.monotonic()

    def reading(self) -> ArmReading:
        return self.state.reading

    def estimate(self) -> ObjectEstimate:
        """What the robot's object detector reports at the newest state."""
        return ObjectEstimate(self.state.object_pose, self.state.object_velocity, self.object_shape, self.object_size)

    def command(self, ctrl: np.ndarray) -> None:
        """Sends servo targets [J + F] stamped with this tick's start (or, at the fault's tick, injects it)."""
        stamp = self.schedule.stamp
        self._seq += 1
        fault = self.fault
        kind = fault.kind if fault is not None and fault.tick == self.schedule.tick else None
        if kind == "drop":
            return
        if kind is not None:
            time.sleep(STALL_SECONDS if kind == "stall" else 1.5 * self.timing.latency_budget)
        self._socket.send(wire.encode_command(wire.Command(wire.TARGET, self._seq, stamp, ctrl)))
        self.deadline_misses += time.monotonic() > stamp + self.timing.latency_budget

    def step(self) -> None:
        """Waits for the next tick's slot and reads the robot's newest state; `RobotStopped` where it is holding or
        stopped, or its newest state is older than a deadline."""
        self.schedule.wait()
        while self._socket.poll(0):
            self.state = wire.decode_state(self._socket.recv())
        if self.state.status != wire.RUNNING:
            raise RobotStopped(f"the robot held and stopped: {wire.FAULTS[self.state.fault]}")
        if time.monotonic() - self.state.time > self.timing.deadline:
            raise RobotStopped(f"no state from the robot for {time.monotonic() - self.state.time:.3f} s")

    def end(self) -> wire.State:
        """Tells the robot the run is over; its last state, once it has held and stopped (`RobotStopped` if it sends
        none within the connect timeout)."""
        self._seq += 1
        wire.send(self._socket, wire.encode_command(wire.Command(wire.END, self._seq, time.monotonic(), np.zeros(0))))
        while self.state.status != wire.STOPPED:
            if not self._socket.poll(round(self.timing.connect_timeout * 1000)):
                raise RobotStopped(f"the robot did not stop within {self.timing.connect_timeout} s of the end")
            self.state = wire.decode_state(self._socket.recv())
        return self.state

    def close(self) -> None:
        self._socket.close(linger=0)
        self._context.term()
