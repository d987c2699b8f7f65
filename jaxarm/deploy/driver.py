"""The robot's side of a real-time rehearsal: stock MuJoCo as the robot, in a process of its own, stepped in
wall-clock time at the servo rate behind a zmq socket, as a robot's driver would be. Imports numpy, mujoco, zmq and
ruckig alone.

Each servo tick (1 kHz) it takes the policy's newest targets (`wire.Command`, 25 Hz), sends the arm the next
setpoint of a jerk-limited stream towards them (`stream.ServoStream`) and steps the physics one servo period; every
`Timing.publish_period` it sends its state (`wire.State`). Its watchdog is the safe reaction: when a command misses
its deadline (one control period and the latency budget after the last one's tick), one is missing from the
sequence, one is not finite, or the policy ends, the arm holds (brakes to rest within its limits, the gripper
keeping its grip), then stops: the driver sends its last state, takes no more commands, and writes the setpoints it
streamed (`StreamLog`).

J and F are the arm's joint and finger counts (`DriverSetup.description`'s `arm_joints` and `finger_joints`).
"""

import dataclasses
import multiprocessing
import time
from typing import Any

import mujoco
import numpy as np
import zmq

from jaxarm.deploy import wire
from jaxarm.deploy.clock import sleep_until
from jaxarm.deploy.mujoco_robot import MujocoRobot
from jaxarm.deploy.stream import ServoStream
from jaxarm.robots import PANDA, RobotDescription


@dataclasses.dataclass(frozen=True)
class DriverSetup:
    """What the robot process starts from (picklable: a spawned process gets it whole).

    Attributes:
      address: the zmq address it binds (`ipc://...` or `tcp://...`).
      model_path: the scene as MuJoCo's binary model (.mjb); stepped at `timing.servo_period`.
      qpos: [nq] the scene's start positions (the arm at rest).
      ctrl: [J + F] the servos' start targets (arm, fingers).
      object_qpos: int [N, 7] where each object's pose is in qpos (what a detector reports; [0, 7] for none).
      object_qvel: int [N, 6] where each object's velocity is in qvel.
      timing: the rehearsal's clocks and deadlines.
      log_path: where the streamed setpoints are written (.npz, `StreamLog`'s fields).
      description: the robot in the scene (its names, joint count and limits).
    """

    address: str
    model_path: str
    qpos: np.ndarray
    ctrl: np.ndarray
    object_qpos: np.ndarray
    object_qvel: np.ndarray
    timing: wire.Timing
    log_path: str
    description: RobotDescription = PANDA


@dataclasses.dataclass
class StreamLog:
    """What the driver streamed, one row per servo tick.

    Attributes:
      position, velocity, acceleration: [T, J] the setpoints sent to the arm.
      lateness: [T] seconds each servo tick started after its slot on the wall clock.
      fault: the code (`wire.FAULTS`) of what made the arm hold; `NO_FAULT` if no command ever came.
      hold_tick, stop_tick: the servo ticks at which it began to hold and came to rest (-1: never).
    """

    position: list = dataclasses.field(default_factory=list)
    velocity: list = dataclasses.field(default_factory=list)
    acceleration: list = dataclasses.field(default_factory=list)
    lateness: list = dataclasses.field(default_factory=list)
    fault: int = wire.NO_FAULT
    hold_tick: int = -1
    stop_tick: int = -1

    def save(self, path: str) -> None:
        fields = dataclasses.fields(self)
        arrays: dict[str, Any] = {field.name: np.asarray(getattr(self, field.name)) for field in fields}
        np.savez(path, **arrays)


def judge(command: wire.Command, now: float, last: wire.Command, timing: wire.Timing) -> int:
    """The fault (`wire` code) a command arriving at `now` shows, after the `last` one followed: `ENDED`, `DROPPED`
    where its number is not the next, `MISSED` past the last one's deadline, `UNSAFE` with targets not finite, else
    `NO_FAULT`."""
    if command.kind == wire.END:
        return wire.ENDED
    if command.seq != last.seq + 1:
        return wire.DROPPED
    if now > last.stamp + timing.deadline:
        return wire.MISSED
    if not np.all(np.isfinite(command.ctrl)):
        return wire.UNSAFE
    return wire.NO_FAULT


def receive(socket: zmq.Socket) -> list[wire.Command]:
    """Every command waiting on `socket`, oldest first, without blocking."""
    commands = []
    while socket.poll(0):
        commands.append(wire.decode_command(socket.recv()))
    return commands


def state_message(robot: MujocoRobot, setup: DriverSetup, status: int, fault: int) -> bytes:
    data = robot.data
    pose, velocity = data.qpos[setup.object_qpos], data.qvel[setup.object_qvel]
    return wire.encode_state(wire.State(status, fault, time.monotonic(), robot.reading(), pose, velocity))


def stream_commands(robot: MujocoRobot, socket: zmq.Socket, setup: DriverSetup) -> StreamLog:
    """The real-time loop, from the policy's first message (number 0) until the arm has held and stopped. The first
    target is due one deadline after the start, as if that message had been stamped then."""
    timing, log = setup.timing, StreamLog()
    stream = ServoStream(robot.reading().arm_q, timing.servo_period, timing.arrival, setup.description.joint_limits)
    joints = robot.joints
    start = time.monotonic()
    last = wire.Command(wire.TARGET, 0, start, setup.ctrl)
    tick = 0
    while True:
        log.lateness.append(sleep_until(start + tick * timing.servo_period))
        now = time.monotonic()
        for command in receive(socket):
            log.fault = log.fault or judge(command, now, last, timing)
            if not log.fault:
                target = command.ctrl[:joints]
                stream.retarget(target, (target - last.ctrl[:joints]) / timing.control_period)
                last = command
        if not log.fault and now > last.stamp + timing.deadline:
            log.fault = wire.MISSED
        if log.fault and not stream.holding:
            stream.hold()
            log.hold_tick = tick
        point = stream.next()
        # The gripper keeps its last target while the arm holds: an object in its grasp stays there.
        robot.command(np.concatenate([point.position, last.ctrl[joints:]]))
        robot.step()
        log.position.append(point.position)
        log.velocity.append(point.velocity)
        log.acceleration.append(point.acceleration)
        if stream.at_rest:
            break
        if tick % timing.publish_every == 0:
            wire.send(socket, state_message(robot, setup, wire.HOLDING if stream.holding else wire.RUNNING, log.fault))
        tick += 1
    log.stop_tick = tick
    wire.send(socket, state_message(robot, setup, wire.STOPPED, log.fault))
    return log


def first_message_comes(socket: zmq.Socket, timeout_s: float) -> bool:
    """Whether the policy's first message comes within `timeout_s`; False at once where the process that started
    this one has gone (a rehearsal stopped by Ctrl-C, or killed, before it connected: the robot process waited out
    its 20 s alone)."""
    parent = multiprocessing.parent_process()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if socket.poll(100):
            return True
        if parent is not None and not parent.is_alive():
            return False
    return False


def serve(setup: DriverSetup) -> None:
    """The robot process: binds `setup.address`, waits for the policy's first message (which starts its clock),
    streams until the arm has held and stopped, and writes the `StreamLog` (an empty one if no message came within
    the connect timeout)."""
    model = mujoco.MjModel.from_binary_path(setup.model_path)
    model.opt.timestep = setup.timing.servo_period
    robot = MujocoRobot(model, setup.timing.servo_period, setup.description)
    robot.data.qpos[:] = setup.qpos
    robot.command(setup.ctrl)
    mujoco.mj_forward(model, robot.data)
    context = zmq.Context()
    socket = context.socket(zmq.PAIR)
    socket.bind(setup.address)
    try:
        log = StreamLog()
        if first_message_comes(socket, setup.timing.connect_timeout):
            socket.recv()
            log = stream_commands(robot, socket, setup)
        log.save(setup.log_path)
    finally:
        socket.close(linger=0)
        context.term()
